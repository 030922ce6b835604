//! Criterion benchmark of the dynamic projection: one call over a 20 ms period (kinematics, J,
//! M, h and one cone program updated in place) from each scene's initial state, a request
//! straight ahead beyond reach, on the cart with a tall mass (tests/data/cart_tall_mass.yaml:
//! two friction cones, a unilateral caster: 8 coordinates, 7 rows), the floating mobile
//! manipulator (params/mobile_manipulator_floating.yaml: 12 coordinates, 7 rows, the arm held by
//! the request's bounds) and the planar diff drive (params/diff_drive.yaml: efforts only).

use constraint_dynamics::envelope::EnvelopeModel;
use constraint_dynamics::projection::{DynamicProjector, ProjectionProblem};
use constraint_dynamics::{Scene, System};
use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;
use std::path::PathBuf;

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("projection_dynamic");
    for (name, file) in [
        ("cart_tall_mass", "tests/data/cart_tall_mass.yaml"),
        (
            "mobile_manipulator_floating",
            "params/mobile_manipulator_floating.yaml",
        ),
        ("diff_drive", "params/diff_drive.yaml"),
    ] {
        let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(file);
        let scene = Scene::load(&path).expect("scene");
        let mut sys = System::from_scene(&scene).expect("system");
        let em = EnvelopeModel::from_scene(&scene, &sys).expect("envelope model");
        let mut proj = DynamicProjector::new(sys.model(), sys.constraints());
        let nv = sys.model().nv;
        let zero = vec![0.0; nv];
        let mut p = ProjectionProblem::new(sys.model());
        p.v_des[0] = 5.0;
        if name == "mobile_manipulator_floating" {
            // The arm (the coordinates after the base's six and the two wheels) held.
            for i in 8..nv {
                p.lower[i] = 0.0;
                p.upper[i] = 0.0;
            }
        }
        let (q, v) = (scene.q0.clone(), scene.v0.clone());
        proj.project(&mut sys, Some(&em), &q, &v, &zero, &p, 0.02)
            .expect("projection");
        g.bench_function(format!("{name}/period_20ms"), |b| {
            b.iter(|| {
                let o = proj
                    .project(&mut sys, Some(&em), black_box(&q), &v, &zero, &p, 0.02)
                    .expect("projection");
                black_box(o.qp_iterations);
            })
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
