//! The hot path allocates nothing: RNEA, CRBA, ABA, the bias forces and the constrained dynamics
//! (multiplier form, full-rank constraints) run with a counting global allocator.

mod common;
use common::*;
use constraint_dynamics::algorithm::*;
use constraint_dynamics::constraints::{ConstraintData, ConstraintSet};
use constraint_dynamics::dynamics::{Baumgarte, KktWorkspace, constrained_forward_dynamics};
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

struct Counting;
static ALLOCS: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        ALLOCS.fetch_add(1, Ordering::SeqCst);
        unsafe { System.alloc(l) }
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        unsafe { System.dealloc(p, l) }
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, n: usize) -> *mut u8 {
        ALLOCS.fetch_add(1, Ordering::SeqCst);
        unsafe { System.realloc(p, l, n) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn count<F: FnMut()>(mut f: F) -> usize {
    let before = ALLOCS.load(Ordering::SeqCst);
    f();
    ALLOCS.load(Ordering::SeqCst) - before
}

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
            count(|| {
                rnea(&model, &mut data, &q, &v, &tau);
            }),
            0,
            "{name}: rnea allocates"
        );
        assert_eq!(
            count(|| {
                nonlinear_effects(&model, &mut data, &q, &v);
            }),
            0,
            "{name}: nle allocates"
        );
        assert_eq!(
            count(|| {
                crba(&model, &mut data, &q);
            }),
            0,
            "{name}: crba allocates"
        );
        assert_eq!(
            count(|| {
                aba(&model, &mut data, &q, &v, &tau);
            }),
            0,
            "{name}: aba allocates"
        );
        assert_eq!(
            count(|| {
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
