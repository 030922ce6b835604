//! Criterion benchmark of the acceleration envelope: one whole call (kinematics, J, γ, M, h and
//! the four cone programs: forward acceleration and deceleration, yaw left and right) at a
//! scene's initial state, on the floating mobile manipulator (params/mobile_manipulator_floating.yaml:
//! two rolling wheels without μ, a unilateral caster, the arm held: 12 coordinates, 7 rows) and
//! on the cart with a tall mass (tests/data/cart_tall_mass.yaml: two friction cones, a unilateral
//! caster: 8 coordinates, 7 rows).

use constraint_dynamics::envelope::{EnvelopeData, EnvelopeModel, acceleration_envelope};
use constraint_dynamics::{Scene, System};
use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;
use std::path::PathBuf;

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("envelope");
    for (name, file) in [
        (
            "mobile_manipulator_floating",
            "params/mobile_manipulator_floating.yaml",
        ),
        ("cart_tall_mass", "tests/data/cart_tall_mass.yaml"),
    ] {
        let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(file);
        let scene = Scene::load(&path).expect("scene");
        let mut sys = System::from_scene(&scene).expect("system");
        let em = EnvelopeModel::from_scene(&scene, &sys).expect("envelope model");
        let mut ed = EnvelopeData::new(&em);
        let zero = vec![0.0; sys.model().nv];
        let (q, v) = (scene.q0.clone(), scene.v0.clone());
        acceleration_envelope(&mut sys, &em, &mut ed, &q, &v, &zero).expect("envelope");
        g.bench_function(format!("{name}/four_limits"), |b| {
            b.iter(|| {
                let e = acceleration_envelope(&mut sys, &em, &mut ed, black_box(&q), &v, &zero)
                    .expect("envelope");
                black_box(e.forward_deceleration.max);
            })
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
