//! The multiplier form without M (`dynamics::tree_multipliers`: q̈_free and each column of
//! M⁻¹Jᵀ by ABA's passes, O(n·m² + m³)) against the dense path (CRBA, the LTL factor of M and
//! its Schur complement, checked against Pinocchio in `reference_dynamics`):
//!
//! - On every bundled scene whose multiplier form both paths take (loops, held frames,
//!   distances, couplings, mimic, rolling wheels, velocity constraints; fixed, planar and
//!   floating bases), at the scene's start and at states off it: q̈ and λ agree to 1e-12
//!   relative to max(1, max |·|) (achieved ≤ 1.1e-13), and so do the rank deficiency of redundant sets (two wheels
//!   on one axle) and their minimum-norm λ.
//! - A 200-link chain held at both ends (its end point at its start position, computed here
//!   from the chain's geometry, not the model's kinematics), where `System` takes the linear
//!   path: λ agrees to 1e-12 (achieved 3.2e-14), q̈ to 5e-11 (1.0e-11: M's conditioning on a
//!   long chain sets both paths' rounding, as without the end held), and J q̈ equals the
//!   Baumgarte right side −γ − K_d J v − K_p φ.
//! - Where ABA's pivots fail (a massless rod the constraints fix), the linear path declines.
//! - A 60-link chain held at both ends falls for 0.3 s (RK4, the drift projection in the mass
//!   metric by ABA's factors) conserving its energy and keeping its end on its point.

use crate::chain;
use crate::common::*;
use constraint_dynamics::algorithm::Data;
use constraint_dynamics::constraints::{ConstraintData, ConstraintSet};
use constraint_dynamics::dynamics::{
    KktOptions, KktWorkspace, TreeKktWorkspace, constrained_forward_dynamics, takes_linear_path,
    tree_constrained_forward_dynamics,
};
use constraint_dynamics::predict::{PredictionRequest, Predictor};
use constraint_dynamics::{Model, Scene, System};

/// (q̈, λ, rank deficiency) of one path at (q, v, τ); None where it declines or errs.
type Outcome = Option<(Vec<f64>, Vec<f64>, usize)>;

fn both_paths(
    m: &Model,
    set: &ConstraintSet,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
    opts: KktOptions,
) -> (Outcome, Outcome) {
    let (mut data, mut cd) = (Data::new(m), ConstraintData::new(m, set));
    let mut kkt = KktWorkspace::new(m, set);
    let dense = constrained_forward_dynamics(m, &mut data, set, &mut cd, &mut kkt, q, v, tau, opts)
        .ok()
        .map(|_| {
            (
                kkt.qdd.as_slice().to_vec(),
                kkt.lambda.as_slice().to_vec(),
                kkt.rank_deficiency,
            )
        });
    let (mut data, mut cd) = (Data::new(m), ConstraintData::new(m, set));
    let mut kkt = KktWorkspace::new(m, set);
    let mut tree = TreeKktWorkspace::new(m);
    let linear = match tree_constrained_forward_dynamics(
        m, &mut data, set, &mut cd, &mut kkt, &mut tree, q, v, tau, opts,
    ) {
        Ok(true) => Some((
            kkt.qdd.as_slice().to_vec(),
            kkt.lambda.as_slice().to_vec(),
            kkt.rank_deficiency,
        )),
        _ => None,
    };
    (dense, linear)
}

/// A reproducible uniform draw in [−1, 1) (xorshift64*).
fn draw(state: &mut u64) -> f64 {
    *state ^= *state >> 12;
    *state ^= *state << 25;
    *state ^= *state >> 27;
    let x = state.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11;
    2.0 * (x as f64 / (1u64 << 53) as f64) - 1.0
}

#[test]
fn the_linear_multiplier_form_agrees_with_the_dense_one_on_the_bundled_scenes() {
    let (mut compared, mut redundant) = (Vec::new(), 0);
    let mut seed = 0x9E37_79B9_7F4A_7C15u64;
    for path in bundled_scenes() {
        let scene = Scene::load(&path).unwrap();
        let sys = System::from_scene(&scene).unwrap();
        let set = sys.constraints().clone();
        if set.is_empty() {
            continue;
        }
        let m: &Model = &scene.model;
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        let (mut agreed, mut start_redundant) = (0, false);
        for k in 0..4 {
            // The start, then states 0.05 rad / 0.1 rad/s off it (off the constraints: the
            // Baumgarte terms are exercised). A redundant set keeps the start's configuration:
            // moved off it, its dependent rows become nearly dependent, where the rank is
            // decided by rounding at the solver's pivot tolerance, whichever path formed S
            // (both λ then huge and opposite, q̈ the same to 1e-5).
            let off = if k == 0 || start_redundant { 0.0 } else { 0.05 };
            let delta: Vec<f64> = (0..m.nv).map(|_| off * draw(&mut seed)).collect();
            let mut q = vec![0.0; m.nq];
            m.integrate(&scene.q0, &delta, 1.0, &mut q);
            let v: Vec<f64> = (0..m.nv)
                .map(|i| scene.v0[i] + if k == 0 { 0.0 } else { 0.1 * draw(&mut seed) })
                .collect();
            let tau: Vec<f64> = (0..m.nv).map(|_| draw(&mut seed)).collect();
            let opts = KktOptions {
                gains: constraint_dynamics::dynamics::Baumgarte {
                    kp: 100.0,
                    kd: 20.0,
                },
                allow_inconsistent: true,
                ..Default::default()
            };
            let (dense, linear) = both_paths(m, &set, &q, &v, &tau, opts);
            let (Some(dense), Some(linear)) = (dense, linear) else {
                continue;
            };
            let what = format!("{name} state {k}");
            assert_close(&format!("{what} q̈"), &linear.0, &dense.0, 1e-12);
            assert_close(&format!("{what} λ"), &linear.1, &dense.1, 1e-12);
            assert_eq!(linear.2, dense.2, "{what}: rank deficiency");
            redundant += usize::from(dense.2 > 0);
            start_redundant |= k == 0 && dense.2 > 0;
            agreed += 1;
        }
        if agreed > 0 {
            compared.push(name);
        }
    }
    // Every scene with constraints but the massless rod (its pivot is refused) and the
    // velocity-determined rows (their force is not along J: the dense path names them).
    assert!(compared.len() >= 13, "compared only {compared:?}");
    assert!(redundant > 0, "no redundant set was compared: {compared:?}");
}

#[test]
fn a_chain_held_at_both_ends_takes_the_linear_path() {
    let n = 200;
    let scene = chain::load_chain_scene(n, true);
    let m: &Model = &scene.model;
    assert!(takes_linear_path(m));
    let mut sys = System::from_scene(&scene).unwrap();
    let set = sys.constraints().clone();
    assert_eq!(set.nrows, 3);
    let gains = KktOptions::default().gains;
    let mut seed = 17u64;
    for k in 0..3 {
        let q = chain::chain_q0(n);
        // At rest the held end is where the generator put it: φ = 0 to rounding.
        let v: Vec<f64> = (0..n)
            .map(|_| if k == 0 { 0.0 } else { draw(&mut seed) })
            .collect();
        let tau: Vec<f64> = (0..n).map(|_| 0.1 * draw(&mut seed)).collect();
        let qdd = sys
            .forward_dynamics(&q, &v, &tau, true)
            .unwrap()
            .as_slice()
            .to_vec();
        let lambda = sys.lambda().as_slice().to_vec();
        let rows = sys.rows();
        let phi = rows.phi.amax();
        assert!(phi < 1e-12, "the held end is {phi:e} m off its point");
        let (dense, _) = both_paths(m, &set, &q, &v, &tau, gains.into());
        let dense = dense.expect("the dense path accepts the chain");
        assert_close(&format!("chain state {k} q̈"), &qdd, &dense.0, 5e-11);
        assert_close(&format!("chain state {k} λ"), &lambda, &dense.1, 1e-12);
        let rows = sys.rows();
        for r in 0..3 {
            let jq: f64 = (0..n).map(|c| rows.j[(r, c)] * qdd[c]).sum();
            let b = -rows.gamma[r] - gains.kd * rows.jv[r] - gains.kp * rows.phi[r];
            let scale = b.abs().max(1.0);
            assert!(
                (jq - b).abs() < 1e-9 * scale,
                "chain state {k} row {r}: J q̈ {jq} against {b}"
            );
        }
    }
}

#[test]
fn a_massless_rod_is_left_to_the_dense_path() {
    let scene = Scene::load(repo_dir().join("params/rod_body.yaml")).unwrap();
    let sys = System::from_scene(&scene).unwrap();
    let set = sys.constraints().clone();
    let m: &Model = &scene.model;
    let tau = vec![0.0; m.nv];
    let (dense, linear) = both_paths(m, &set, &scene.q0, &scene.v0, &tau, KktOptions::default());
    assert!(dense.is_some(), "the dense path's augmented form solves it");
    assert!(
        linear.is_none(),
        "ABA's pivot of the massless rod was accepted"
    );
}

/// A 60-link chain held at both ends (the linear path: mean depth 30.5) falls from rest for
/// 0.3 s under RK4 at 1 ms with the scene's default drift projection, which on such a tree
/// projects in the mass metric by ABA's factors (`System::tree_metric`). No force does work:
/// the energy is conserved (to the step's error and the projection's: 1.6e-9 of the kinetic
/// energy it gains), and the held end stays on its point.
#[test]
fn a_held_chain_falls_keeping_its_energy_and_its_end() {
    let scene = chain::load_chain_scene(60, true);
    assert!(takes_linear_path(&scene.model));
    let mut p = Predictor::from_scene(&scene).unwrap();
    let traj = p
        .predict(&PredictionRequest::new(&scene.q0, &scene.v0).horizon(0.3))
        .unwrap();
    let s0 = &traj.samples[0];
    let e0 = s0.kinetic_energy + s0.potential_energy;
    let (mut drift, mut ke_max, mut phi) = (0.0f64, 0.0f64, 0.0f64);
    for s in &traj.samples {
        drift = drift.max((s.kinetic_energy + s.potential_energy - e0).abs());
        ke_max = ke_max.max(s.kinetic_energy);
        phi = phi.max(s.position_residual);
    }
    eprintln!("achieved: energy drift {drift:.3e} J of {ke_max:.3e} J kinetic; |φ| ≤ {phi:.1e} m");
    assert!(ke_max > 1e-3, "the chain did not fall: {ke_max} J");
    // Achieved 3.6e-8 J of 22 J.
    assert!(
        drift < 5e-9 * ke_max,
        "energy drift {drift} J of {ke_max} J"
    );
    assert!(phi < 1e-12, "the held end is {phi} m off its point");
}
