//! The stepping loop allocates nothing: with a counting allocator, a prediction with 4× the steps
//! (and the same samples) makes exactly as many allocations — every method, with projection, on a
//! constrained scene (fourbar, full-rank loop) and with force elements (stiff chain).

use constraint_dynamics::Scene;
use constraint_dynamics::predict::{DriftControl, Method, Predictor};
use std::alloc::{GlobalAlloc, Layout, System};
use std::path::PathBuf;
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

/// Allocations of one prediction over `horizon` with two samples (t = 0 and the end).
fn allocations(p: &mut Predictor, sc: &Scene, horizon: f64) -> usize {
    p.settings.sample_period = horizon;
    let before = ALLOCS.load(Ordering::SeqCst);
    let t = p.predict(&sc.q0, &sc.v0, &[], horizon).unwrap();
    let n = ALLOCS.load(Ordering::SeqCst) - before;
    assert_eq!(t.samples.len(), 2);
    drop(t);
    n
}

#[test]
fn stepping_allocates_nothing_per_step() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let cases = [
        ("params/fourbar.yaml", 1e-3),
        ("params/report/spring_chain_stiff.yaml", 1e-5),
    ];
    for (rel, dt) in cases {
        let sc = Scene::load(root.join(rel)).unwrap();
        for method in [
            Method::SemiImplicitEuler,
            Method::Rk4,
            Method::Dopri5,
            Method::Sdirk2,
        ] {
            let mut p = Predictor::from_scene(&sc).unwrap();
            p.settings.method = method;
            p.settings.dt = dt;
            p.settings.drift = DriftControl::Projection;
            let h = 100.0 * dt;
            allocations(&mut p, &sc, h); // warm-up
            let (short, long) = (
                allocations(&mut p, &sc, h),
                allocations(&mut p, &sc, 4.0 * h),
            );
            println!(
                "{rel} {method:?}: {short} allocations over {h} s, {long} over {} s",
                4.0 * h
            );
            assert_eq!(short, long, "{rel} {method:?}: the steps allocate");
        }
    }
}
