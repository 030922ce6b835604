//! The hot path allocates nothing: RNEA, CRBA, ABA, the bias forces and the constrained dynamics
//! (multiplier form, full-rank constraints) run with a counting global allocator.

use crate::common;
use common::*;
use constraint_dynamics::algorithm::*;
use constraint_dynamics::constraints::{ConstraintData, ConstraintSet};
use constraint_dynamics::dynamics::{Baumgarte, KktWorkspace, constrained_forward_dynamics};

use crate::counting_alloc;
use counting_alloc::allocations;

#[test]
fn algorithms_and_constrained_dynamics_do_not_allocate() {
    for name in ["ur5_ee_point", "solo12_four_feet"] {
        let case = load_case(name);
        let model = case_model(&case);
        let st = &case["states"][1];
        let (q, v, tau) = (vecf(&st["q"]), vecf(&st["qd"]), vecf(&st["tau"]));
        let specs = specs_for(&case, st);
        let set = ConstraintSet::new(&model, &specs, &q).unwrap();
        let mut data = Data::new(&model);
        let mut cd = ConstraintData::new(&model, &set);
        let mut ws = KktWorkspace::new(&model, &set);
        let b = Baumgarte {
            kp: 100.0,
            kd: 20.0,
        };
        // Warm up once (lazy statics, first-touch), then count.
        constrained_forward_dynamics(&model, &mut data, &set, &mut cd, &mut ws, &q, &v, &tau, b)
            .unwrap();
        assert_eq!(
            allocations(|| {
                rnea(&model, &mut data, &q, &v, &tau);
            }),
            0,
            "{name}: rnea allocates"
        );
        assert_eq!(
            allocations(|| {
                nonlinear_effects(&model, &mut data, &q, &v);
            }),
            0,
            "{name}: nle allocates"
        );
        assert_eq!(
            allocations(|| {
                crba(&model, &mut data, &q);
            }),
            0,
            "{name}: crba allocates"
        );
        assert_eq!(
            allocations(|| {
                aba(&model, &mut data, &q, &v, &tau);
            }),
            0,
            "{name}: aba allocates"
        );
        assert_eq!(
            allocations(|| {
                constrained_forward_dynamics(
                    &model, &mut data, &set, &mut cd, &mut ws, &q, &v, &tau, b,
                )
                .unwrap();
            }),
            0,
            "{name}: constrained dynamics allocates"
        );
        assert_eq!(ws.rank_deficiency, 0);
    }
}

#[test]
fn derivatives_do_not_allocate() {
    use constraint_dynamics::derivatives::*;
    for name in ["fourbar", "ur5_ee_point", "solo12_four_feet"] {
        let case = load_case(name);
        let model = case_model(&case);
        let st = &case["states"][1];
        let (q, v, tau) = (vecf(&st["q"]), vecf(&st["qd"]), vecf(&st["tau"]));
        let set = ConstraintSet::new(&model, &specs_for(&case, st), &q).unwrap();
        let mut data = Data::new(&model);
        let mut cd = ConstraintData::new(&model, &set);
        let mut ws = KktWorkspace::new(&model, &set);
        let mut dd = DerivativeData::new(&model, set.nrows);
        let mut free = DerivativeData::new(&model, 0);
        let b = Baumgarte {
            kp: 100.0,
            kd: 20.0,
        };
        let mut all = || {
            rnea_derivatives(&model, &mut data, &mut free, &q, &v, &tau);
            aba_derivatives(&model, &mut data, &mut free, &q, &v, &tau).unwrap();
            constrained_dynamics_derivatives(
                &model, &mut data, &set, &mut cd, &mut ws, &mut dd, &q, &v, &tau, b,
            )
            .unwrap();
        };
        all(); // warm up
        let r = allocations(|| rnea_derivatives(&model, &mut data, &mut free, &q, &v, &tau));
        let a = allocations(|| {
            aba_derivatives(&model, &mut data, &mut free, &q, &v, &tau).unwrap();
        });
        let c = allocations(|| {
            constrained_dynamics_derivatives(
                &model, &mut data, &set, &mut cd, &mut ws, &mut dd, &q, &v, &tau, b,
            )
            .unwrap();
        });
        assert_eq!(
            (r, a, c),
            (0, 0, 0),
            "{name}: derivatives allocate (rnea, aba, constrained)"
        );
    }
}

#[test]
fn step_linearization_does_not_allocate() {
    use constraint_dynamics::predict::{Linearization, Method, linearize_step};
    use constraint_dynamics::{Scene, System};
    // Full-rank scenes and a wheeled base whose rolling rows are dependent (minimum-norm λ).
    for file in [
        "params/fourbar.yaml",
        "params/double_fourbar.yaml",
        "params/pendulum_a01.yaml",
        "params/mobile_manipulator.yaml",
    ] {
        let scene = Scene::load(repo_dir().join(file)).unwrap();
        let mut sys = System::from_scene(&scene).unwrap();
        let mut lin = Linearization::new(&sys);
        let tau = vec![0.1; sys.model().nv];
        let (q, v) = (scene.q0.clone(), scene.v0.clone());
        for method in [Method::SemiImplicitEuler, Method::Rk4, Method::Dopri5] {
            linearize_step(&mut sys, &mut lin, method, 0.0, &q, &v, &tau, 0.01).unwrap();
            let n = allocations(|| {
                linearize_step(&mut sys, &mut lin, method, 0.0, &q, &v, &tau, 0.01).unwrap();
            });
            assert_eq!(n, 0, "{file} {method:?}: linearize_step allocates");
        }
    }
}
