//! Every bundled scene (params/ and params/report/) evaluates its constrained dynamics without
//! allocating, in both formulations: the rank-deficient ones (diff drive and mobile manipulator,
//! whose rolling contacts stack dependent rows, so the multipliers take the minimum-norm path),
//! the rolling disk and the embedded form included.

use crate::common;
use common::*;
use constraint_dynamics::dynamics::Formulation;
use constraint_dynamics::system::DynamicsOptions;
use constraint_dynamics::{Scene, System};

use crate::counting_alloc;
use counting_alloc::allocations;

fn all_scenes() -> Vec<std::path::PathBuf> {
    let mut v = bundled_scenes();
    let report = repo_dir().join("params/report");
    let mut r: Vec<_> = std::fs::read_dir(report)
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "yaml"))
        .collect();
    r.sort();
    v.extend(r);
    v
}

#[test]
fn dynamics_allocate_nothing_on_every_bundled_scene() {
    let scenes = all_scenes();
    assert!(scenes.len() >= 17, "bundled scenes missing: {scenes:?}");
    let mut deficient = vec![];
    for p in &scenes {
        let name = p.file_stem().unwrap().to_string_lossy().to_string();
        let scene = Scene::load(p).unwrap_or_else(|e| panic!("{name}: {e}"));
        let mut sys = System::from_scene(&scene).unwrap();
        let nv = sys.model().nv;
        let tau: Vec<f64> = (0..nv).map(|i| ((i + 1) as f64 * 0.9).sin()).collect();
        let (q, v) = (scene.q0.clone(), scene.v0.clone());
        for formulation in [Formulation::Multipliers, Formulation::Embedded] {
            let opts = DynamicsOptions {
                formulation,
                allow_inconsistent: false,
                ..Default::default()
            };
            // Warm up once (first touch of lazily sized buffers), then count.
            sys.forward_dynamics_with(&q, &v, &tau, opts)
                .unwrap_or_else(|e| panic!("{name} {formulation:?}: {e}"));
            let n = allocations(|| {
                sys.forward_dynamics_with(&q, &v, &tau, opts).unwrap();
            });
            assert_eq!(n, 0, "{name} {formulation:?}: the dynamics allocate");
            if formulation == Formulation::Multipliers && sys.multipliers().rank_deficiency > 0 {
                deficient.push((name.clone(), sys.multipliers().rank_deficiency));
            }
        }
    }
    println!("rank-deficient scenes (nc − rank): {deficient:?}");
    // The minimum-norm path ran where the rolling contacts make rows dependent: on a planar base
    // each wheel gives a rolling and a lateral row (no normal row), and the two wheels' lateral
    // rows are the same row (4 rows, rank 3 = nv 5 − 2 degrees of freedom v, ω): deficiency 1;
    // the mobile manipulators have the same base. The Bricard's closure (5 rows on 5 joints,
    // 1 DOF) has rank 4.
    for s in [
        "diff_drive",
        "diff_drive_coasting",
        "mobile_manipulator",
        "bricard_a04",
    ] {
        assert!(
            deficient.contains(&(s.to_string(), 1)),
            "{s}: expected rank deficiency 1, got {deficient:?}"
        );
    }
}
