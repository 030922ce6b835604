//! Propagated covariance of a prediction against Monte Carlo (`covariance`'s comparison) on
//! Bricard's mechanism (IFToMM benchmark A04, params/report/bricard_a04.yaml) falling from
//! rest: an over-constrained loop whose closure has a redundant row, consistent on the
//! constraints and not at the off-manifold stages of the linearized steps.

use crate::common;
use crate::covariance::{N_SLOW, TOL, monte_carlo_under, relative_difference};
use common::*;
use constraint_dynamics::Scene;
use constraint_dynamics::predict::{PredictionRequest, Predictor};
use nalgebra::{DMatrix, DVector};

/// The Bricard's closure rows have rank 4 of 5 (Grübler's count says 0 DOF, the mechanism has
/// 1); at the stages of the linearized steps, off the constraints, the redundant row disagrees
/// by up to 2.0e-5 (m/s², rad/s²; above rounding in 496 of 2612 stage evaluations), and those
/// stages take the least-squares multipliers as the prediction's own stages do. Besides the Monte Carlo comparison, the benchmark's own check, energy
/// conservation, and the threefold-symmetric Bricard's configuration curve (joints 1, 3, 5 at
/// one angle and 2, 4 at another) along the nominal run.
#[test]
fn bricard_covariance_matches_monte_carlo() {
    let scene = Scene::load(repo_dir().join("params/report/bricard_a04.yaml")).unwrap();
    let pred = Predictor::from_scene(&scene).unwrap();
    let nv = pred.model().nv;
    let sigma = 1e-3;
    let p0 = DMatrix::identity(2 * nv, 2 * nv) * (sigma * sigma);
    let closure = ClosurePlacement::new(&scene);
    let start = (&scene.q0[..], &scene.v0[..]);
    let place = |q: &mut [f64]| closure.place(q);
    let (p_t, mc) = monte_carlo_under(&pred, start, &[], p0, 1.0, N_SLOW, &place);
    let rel = relative_difference("bricard", &p_t, &mc, N_SLOW);
    assert!(
        rel <= TOL,
        "covariance differs from Monte Carlo by {rel:.3}"
    );

    let mut pred = pred;
    let traj = pred
        .predict(&PredictionRequest::new(&scene.q0, &scene.v0).horizon(1.0))
        .unwrap();
    let energy = |s: &constraint_dynamics::predict::Sample| s.kinetic_energy + s.potential_energy;
    let e0 = energy(&traj.samples[0]);
    let (mut drift, mut asym): (f64, f64) = (0.0, 0.0);
    for s in &traj.samples {
        drift = drift.max((energy(s) - e0).abs());
        let q = &s.q;
        asym = asym.max(
            (q[0] - q[2])
                .abs()
                .max((q[2] - q[4]).abs())
                .max((q[1] - q[3]).abs()),
        );
    }
    let last = &traj.samples.last().unwrap().q;
    eprintln!(
        "bricard: E0 = {e0} J, max |E − E0| = {drift:.2e} J, max joint asymmetry {asym:.2e} rad, \
         q(1 s) = {last:?}"
    );
    // E0 = 9.81 · Σ y_com = −29.43 J at rest. Achieved 1.2e-11 J and 8.3e-14 rad; the joints
    // turn by up to 1.04 rad over the second.
    assert!((e0 + 29.43).abs() < 1e-12, "E0 = {e0}");
    assert!(drift < 1e-9, "energy drift {drift:e} J");
    assert!(asym < 1e-9, "joints 1, 3, 5 or 2, 4 apart by {asym:e} rad");
    assert!(
        last[0] > 1.0,
        "the mechanism did not fall: q(1 s) = {last:?}"
    );
}

/// The Bricard's start configurations put on its closure without moving them along it: Newton
/// on the closure's rows but the redundant one, with the component along the constraint
/// curve's tangent t at the nominal start held (what remains of v along the rows, O(σ²), the
/// predictor's velocity projection removes). Not the predictor's position projection: off the
/// curve the redundant row regains rank in proportion to the distance (singular value 0.4 d²
/// at d·(1, −1, 1, −1, 1) rad), and once it counts its Gauss–Newton step slides the state along
/// the curve — 1.5e-3 rad went to 7.5e-4, changing the energy by 7e-3 J, more than the
/// predictor's energy check lets through.
struct ClosurePlacement {
    sys: constraint_dynamics::System,
    q0: Vec<f64>,
    tangent: DVector<f64>,
    /// The closure rows kept: all but the one the redundancy at q0 weighs most.
    rows: Vec<usize>,
}

impl ClosurePlacement {
    fn new(scene: &Scene) -> Self {
        let mut sys = constraint_dynamics::System::from_scene(scene).unwrap();
        let (q0, v0) = (scene.q0.clone(), scene.v0.clone());
        sys.evaluate_rows(sys.rows().t, &q0, &v0);
        let j = sys.rows().j.clone();
        let (nc, nv) = j.shape();
        let svd = j.svd(true, true);
        // nalgebra's singular values are in descending order: the last is the redundancy's.
        let k = svd.singular_values.len() - 1;
        assert!(svd.singular_values[k] < 1e-12 * svd.singular_values[0] && nc == nv);
        let tangent = svd.v_t.as_ref().unwrap().row(k).transpose();
        let left = svd.u.as_ref().unwrap().column(k).into_owned();
        let drop = left.iamax();
        let rows = (0..nc).filter(|&r| r != drop).collect();
        Self {
            sys,
            q0,
            tangent,
            rows,
        }
    }

    fn place(&self, q: &mut [f64]) {
        let mut sys = self.sys.clone();
        let nv = sys.model().nv;
        let zero = vec![0.0; nv];
        let along = |sys: &constraint_dynamics::System, q: &[f64]| {
            let mut d = vec![0.0; nv];
            sys.model().difference(&self.q0, q, &mut d);
            self.tangent.dot(&DVector::from_vec(d))
        };
        let target = along(&sys, q);
        for _ in 0..20 {
            sys.evaluate_rows(sys.rows().t, q, &zero);
            let mut f = DVector::zeros(nv);
            let mut a = DMatrix::zeros(nv, nv);
            for (i, &r) in self.rows.iter().enumerate() {
                f[i] = sys.rows().phi[r];
                a.row_mut(i).copy_from(&sys.rows().j.row(r));
            }
            f[nv - 1] = along(&sys, q) - target;
            a.row_mut(nv - 1).copy_from(&self.tangent.transpose());
            if f.amax() < 1e-14 {
                return;
            }
            let step = -a.lu().solve(&f).unwrap();
            let start = q.to_vec();
            sys.model().integrate(&start, step.as_slice(), 1.0, q);
        }
        panic!("the closure placement did not converge from {q:?}");
    }
}
