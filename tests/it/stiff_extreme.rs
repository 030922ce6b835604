//! Stiff and extreme propagations: each case states its expected outcome, and either meets its
//! tolerance or returns the typed error it names — never NaN, never a panic, never a silent wrong
//! answer. The measured numbers are printed (`--nocapture`) and tabled in docs/propagation.md.

use crate::closed_forms;
use crate::common;

use closed_forms::{linear_modes, relative_chain_mass};
use common::{scene, very_stiff_chain};
use constraint_dynamics::constraints::ConstraintSpec;
use constraint_dynamics::predict::{
    DriftControl, IntegrationSettings, Method, PredictionRequest, Predictor, Trajectory,
};
use constraint_dynamics::{Error, Scene};
use nalgebra::{DMatrix, DVector};
use std::path::PathBuf;

fn predictor(sc: &Scene, method: Method, dt: f64, drift: DriftControl) -> Predictor {
    predictor_with(sc, method, dt, drift, |_| {})
}

/// [`predictor`] with the other settings `edit` makes.
fn predictor_with(
    sc: &Scene,
    method: Method,
    dt: f64,
    drift: DriftControl,
    edit: impl FnOnce(&mut IntegrationSettings),
) -> Predictor {
    Predictor::from_scene(sc)
        .unwrap()
        .with_settings(|s| {
            s.method = method;
            s.dt = dt;
            s.drift = drift;
            edit(s);
        })
        .unwrap()
}

/// Over `horizon` [s] from the scene's initial state.
fn from_start(sc: &Scene, horizon: f64) -> PredictionRequest<'_> {
    PredictionRequest::new(&sc.q0, &sc.v0).horizon(horizon)
}

fn all_finite(t: &Trajectory) -> bool {
    t.samples.iter().all(|s| {
        s.q.iter().chain(&s.v).all(|x| x.is_finite())
            && s.position_residual.is_finite()
            && s.velocity_residual.is_finite()
    })
}

fn max_residuals(t: &Trajectory) -> (f64, f64) {
    t.samples.iter().fold((0.0f64, 0.0f64), |(p, v), s| {
        (p.max(s.position_residual), v.max(s.velocity_residual))
    })
}

fn energy(s: &constraint_dynamics::predict::Sample) -> f64 {
    s.kinetic_energy + s.potential_energy
}

/// Expected: springs of 1e6–1e8 N/m on 0.1 kg (fastest mode ≈ 4.5e4 rad/s) with an explicit
/// method at dt = 1e-4 s (dt·ω ≈ 4.5 > 2.8) → `Error::StepTooLarge` before the first step, naming
/// the limit.
#[test]
fn explicit_method_with_too_large_a_step_on_stiff_springs_is_refused() {
    let (mut sc, spec) = very_stiff_chain();
    sc.file.forces = spec;
    for method in [Method::Rk4, Method::SemiImplicitEuler] {
        let mut p = predictor(&sc, method, 1e-4, DriftControl::None);
        let err = p.predict(&from_start(&sc, 0.1)).unwrap_err();
        println!("stiff 1e8 N/m, {method:?} dt 1e-4: {err}");
        assert!(matches!(err, Error::StepTooLarge { .. }), "{err}");
    }
}

/// Expected: SDIRK2 (L-stable) at dt = 1e-4 s on the same chain stays stable; the energy
/// ½vᵀMv + ½qᵀKq never increases (to 1e-14 relative) and decays as the stiff modes are damped.
#[test]
fn sdirk2_stays_stable_on_stiff_springs_with_decaying_energy() {
    let (mut sc, spec) = very_stiff_chain();
    sc.file.forces = spec;
    let mut p = predictor_with(&sc, Method::Sdirk2, 1e-4, DriftControl::None, |s| {
        s.sample_period = 1e-3;
        // Damping the unresolved stiff modes is the point: the answer has no correct digit in
        // them, and its error estimate (1.4e-3 m at 4 ms) says so. This test checks stability.
        s.max_error = f64::INFINITY;
    });
    let t = p.predict(&from_start(&sc, 0.2)).unwrap();
    assert!(all_finite(&t));
    let e0 = energy(&t.samples[0]);
    let mut worst_rise: f64 = 0.0;
    for w in t.samples.windows(2) {
        worst_rise = worst_rise.max((energy(&w[1]) - energy(&w[0])) / e0);
    }
    let e_end = energy(t.samples.last().unwrap());
    println!(
        "stiff 1e8 N/m, sdirk2 dt 1e-4 over 0.2 s: E {e0:.4e} → {e_end:.4e} J, largest rise \
         {worst_rise:.1e} of E0, {} steps, {} evaluations",
        t.steps, t.evaluations
    );
    // Achieved: no rise at all (0) and E(0.2 s) = 0.071 E0.
    assert!(worst_rise <= 1e-14, "energy rose by {worst_rise:e} E0");
    assert!(
        e_end < 0.2 * e0,
        "the stiff modes were not damped: {e_end} vs {e0}"
    );
}

const TWO_SLIDERS: &str = r#"<robot name="two_sliders"><link name="base"/>
  <link name="heavy"><inertial><origin xyz="0 0 0" rpy="0 0 0"/><mass value="1.0"/>
    <inertia ixx="1e-4" ixy="0" ixz="0" iyy="1e-4" iyz="0" izz="1e-4"/></inertial></link>
  <link name="light"><inertial><origin xyz="0 0 0" rpy="0 0 0"/><mass value="1e-6"/>
    <inertia ixx="1e-10" ixy="0" ixz="0" iyy="1e-10" iyz="0" izz="1e-10"/></inertial></link>
  <joint name="s1" type="prismatic"><parent link="base"/><child link="heavy"/>
    <origin xyz="0.2 0 0" rpy="0 0 0"/><axis xyz="1 0 0"/>
    <limit lower="-1" upper="1" effort="100" velocity="10"/></joint>
  <joint name="s2" type="prismatic"><parent link="heavy"/><child link="light"/>
    <origin xyz="0.2 0 0" rpy="0 0 0"/><axis xyz="1 0 0"/>
    <limit lower="-1" upper="1" effort="100" velocity="10"/></joint></robot>"#;

/// Expected: masses 1 kg and 1e-6 kg in series (springs 100 N/m and 1e-2 N/m on the relative
/// coordinates: ω ≈ 10 and 100 rad/s, M has condition ~1e6) follow the modal closed form to
/// 1e-9 m with dopri5 (rtol 1e-12) and with RK4 (dt = 1e-4 s) over 2 s.
#[test]
fn mass_ratio_1e6_between_neighbours_matches_the_modal_solution() {
    let yaml = "urdf: two_sliders.urdf\nbase: fixed\ninitial_state: {q: {s1: 0.01, s2: -0.002}}\n\
                forces:\n  joint_springs:\n    - {joint: s1, stiffness: 100.0}\n    \
                - {joint: s2, stiffness: 0.01}\n";
    let file = serde_yaml::from_str(yaml).unwrap();
    let sc = Scene::from_parts(
        &PathBuf::from("two_sliders.yaml"),
        file,
        TWO_SLIDERS,
        "two_sliders.urdf",
    )
    .unwrap();
    let m = relative_chain_mass(&[1.0, 1e-6]);
    let k = DMatrix::from_diagonal(&DVector::from_vec(vec![100.0, 0.01]));
    for (method, dt) in [(Method::Dopri5, 1e-3), (Method::Rk4, 1e-4)] {
        let mut p = predictor_with(&sc, method, dt, DriftControl::None, |s| {
            s.rtol = 1e-12;
            s.atol = 1e-14;
            s.sample_period = 0.01;
        });
        let t = p.predict(&from_start(&sc, 2.0)).unwrap();
        let err = t
            .samples
            .iter()
            .map(|s| {
                let (q, _) = linear_modes(&m, &k, &sc.q0, &sc.v0, s.t);
                s.q.iter()
                    .zip(&q)
                    .map(|(a, b)| (a - b).abs())
                    .fold(0.0, f64::max)
            })
            .fold(0.0, f64::max);
        println!("mass ratio 1e6, {method:?}: max |q − q_modal| = {err:.3e} m");
        // Achieved 9.5e-11 (dopri5), 1.04e-10 (RK4).
        assert!(err <= 1e-9, "{method:?}: {err:e}");
    }
}

/// Expected: the vertical disk spinning at 1e3 rad/s (100 m/s on a 200 m circle) with RK4
/// (dt = 1 ms, projection) over 2 s: no NaN, |J v| ≤ 1e-12 m/s, centre within 1e-9 m of the closed
/// form x = R sin(ωt), y = R(1 − cos ωt); the disk on a floating base (spin 1e3 rad/s, upright)
/// over 0.5 s at dt = 2e-5 s: |φ| ≤ 5e-11 m, |J v| ≤ 2e-12 m/s, relative energy change ≤ 1e-6.
#[test]
fn wheel_spinning_at_1e3_rad_s_keeps_its_constraints() {
    let mut sc = scene("params/vertical_disk.yaml");
    sc.v0 = vec![100.0, 0.0, 0.5, 1000.0];
    let mut p = predictor_with(&sc, Method::Rk4, 1e-3, DriftControl::Projection, |s| {
        s.sample_period = 0.1;
    });
    let t = p.predict(&from_start(&sc, 2.0)).unwrap();
    let (_, jv) = max_residuals(&t);
    let centre = t
        .samples
        .iter()
        .map(|s| {
            let (x, y) = (200.0 * (0.5 * s.t).sin(), 200.0 * (1.0 - (0.5 * s.t).cos()));
            (s.q[0] - x).hypot(s.q[1] - y)
        })
        .fold(0.0, f64::max);
    println!("vertical disk at 1e3 rad/s: max |J v| {jv:.2e} m/s, centre error {centre:.2e} m");
    // Achieved |J v| 1.4e-14 m/s, centre 1.8e-11 m.
    assert!(all_finite(&t), "non-finite samples");
    assert!(jv <= 1e-12, "|J v| {jv:e}");
    assert!(centre <= 1e-9, "centre error {centre:e}");

    let mut sc = scene("params/report/rolling_disk.yaml");
    // Upright at the origin, rolling along x at 100 m/s (spin 1e3 rad/s about the body y axis),
    // turning at 0.5 rad/s and starting to roll over at 0.05 rad/s (consistent: vy = −0.005 m/s).
    sc.q0 = vec![0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 1.0];
    sc.v0 = vec![100.0, -0.005, 0.0, 0.05, 1000.0, 0.5];
    // Nutation runs at ≈ (I_spin / I_tilt) · 1e3 = 2e3 rad/s: dt = 2e-5 s resolves it.
    let mut p = predictor_with(&sc, Method::Rk4, 2e-5, DriftControl::Projection, |s| {
        s.sample_period = 0.01;
    });
    let t = p.predict(&from_start(&sc, 0.5)).unwrap();
    let (phi, jv) = max_residuals(&t);
    let e0 = energy(&t.samples[0]);
    let de = t
        .samples
        .iter()
        .map(|s| (energy(s) - e0).abs() / e0)
        .fold(0.0, f64::max);
    println!(
        "rolling disk (floating) at 1e3 rad/s: max |φ| {phi:.2e} m, max |J v| {jv:.2e} m/s, \
         relative energy change {de:.2e}"
    );
    // Achieved |φ| 1.0e-12 m, |J v| 2.8e-14 m/s, relative energy change 1.5e-8.
    assert!(all_finite(&t), "non-finite samples");
    assert!(phi <= 5e-11, "|φ| {phi:e}");
    assert!(jv <= 2e-12, "|J v| {jv:e}");
    assert!(de <= 1e-6, "relative energy change {de:e}");
}

/// Expected: the double four-bar held at its singular (all links horizontal) position, at rest
/// under gravity: the loop Jacobian drops to rank 2 of 4 — reported as rank deficiency 2 — the
/// multipliers are the minimum-norm ones (finite), and RK4 + projection over 0.5 s gives no NaN
/// and |φ| ≤ 5e-12 m.
#[test]
fn four_bar_at_its_toggle_position_reports_rank_deficiency() {
    let mut sc = scene("params/double_fourbar.yaml");
    sc.q0 = vec![0.0; 5];
    sc.v0 = vec![0.0; 5];
    let mut p = predictor_with(&sc, Method::Rk4, 1e-3, DriftControl::Projection, |s| {
        s.sample_period = 0.05;
    });
    let t = p.predict(&from_start(&sc, 0.5).forces(true)).unwrap();
    let s0 = &t.samples[0];
    let lambda = s0.lambda.as_ref().unwrap();
    let (phi, jv) = max_residuals(&t);
    println!(
        "double four-bar at toggle: rank deficiency {:?}, λ(0) = {lambda:.4?}, max |φ| {phi:.2e}, \
         max |J v| {jv:.2e}, least-squares evaluations {}",
        s0.rank_deficiency, t.least_squares_evaluations
    );
    assert_eq!(s0.rank_deficiency, Some(2));
    assert!(lambda.iter().all(|x| x.is_finite()));
    assert!(
        t.samples
            .iter()
            .all(|s| s.lambda.as_ref().unwrap().iter().all(|x| x.is_finite()))
    );
    // Achieved |φ| 1.1e-13 m.
    assert!(all_finite(&t), "non-finite samples");
    assert!(phi <= 5e-12, "|φ| {phi:e}");
}

/// Expected: the fourbar with its loop closure declared twice (4 rows, rank 2) reports rank
/// deficiency 2, splits the multipliers evenly (minimum norm: each copy carries half of the single
/// declaration's λ, to 2e-12 N) and propagates as the single declaration (2e-13) over 1 s.
#[test]
fn redundant_constraints_give_min_norm_multipliers_and_the_same_motion() {
    let single = scene("params/fourbar.yaml");
    let mut double = single.clone();
    let mut dup = double.file.constraints[0].clone();
    if let ConstraintSpec::Point { name, .. } = &mut dup {
        *name = "loop_closure_again".into();
    }
    double.file.constraints.push(dup);
    let run = |sc: &Scene| {
        let mut p = predictor_with(sc, Method::Rk4, 1e-3, DriftControl::Projection, |s| {
            s.sample_period = 0.1;
        });
        p.predict(&from_start(sc, 1.0).forces(true)).unwrap()
    };
    let (a, b) = (run(&single), run(&double));
    let mut worst_q: f64 = 0.0;
    let mut worst_l: f64 = 0.0;
    for (x, y) in a.samples.iter().zip(&b.samples) {
        assert_eq!(y.rank_deficiency, Some(2));
        let (la, lb) = (x.lambda.as_ref().unwrap(), y.lambda.as_ref().unwrap());
        for r in 0..2 {
            worst_l = worst_l.max(
                (lb[r] - 0.5 * la[r])
                    .abs()
                    .max((lb[r + 2] - 0.5 * la[r]).abs()),
            );
        }
        worst_q =
            x.q.iter()
                .zip(&y.q)
                .map(|(p, q)| (p - q).abs())
                .fold(worst_q, f64::max);
    }
    println!("redundant loop closure: max |λ_dup − λ/2| {worst_l:.2e} N, max |Δq| {worst_q:.2e}");
    // Achieved 4.2e-14 N and 4.9e-15.
    assert!(worst_l <= 2e-12, "|λ_dup − λ/2| {worst_l:e}");
    assert!(worst_q <= 2e-13, "|Δq| {worst_q:e}");
}

/// Expected: 1e5 RK4 steps (fourbar, dt = 1 ms, 100 s) with projection keep |φ| ≤ 5e-11 m and
/// |J v| ≤ 5e-14 m/s at every sample and the energy within 2e-8 J; without drift control the same
/// run drifts (reported for contrast).
#[test]
fn a_horizon_of_1e5_steps_keeps_the_drift_bounded_with_projection() {
    let sc = scene("params/fourbar.yaml");
    for drift in [DriftControl::Projection, DriftControl::None] {
        let mut p = predictor_with(&sc, Method::Rk4, 1e-3, drift, |s| s.sample_period = 0.1);
        let t = p.predict(&from_start(&sc, 100.0)).unwrap();
        let (phi, jv) = max_residuals(&t);
        let e0 = energy(&t.samples[0]);
        let de = t
            .samples
            .iter()
            .map(|s| (energy(s) - e0).abs())
            .fold(0.0, f64::max);
        println!(
            "fourbar 1e5 steps, {drift:?}: {} steps, max |φ| {phi:.2e} m, max |J v| {jv:.2e} m/s, \
             max |ΔE| {de:.2e} J, {:.2} s",
            t.steps, t.run_time_s
        );
        assert_eq!(t.steps, 100_000);
        if drift == DriftControl::Projection {
            // Achieved |φ| 1.0e-12 m, |J v| 2.1e-14 m/s, |ΔE| 3.0e-10 J (|J v| 8.9e-16 when
            // every step is projected; a J v within 16 ε max(1, |v|) is left as it is).
            assert!(phi <= 5e-11, "|φ| {phi:e}");
            assert!(jv <= 5e-14, "|J v| {jv:e}");
            assert!(de <= 2e-8, "|ΔE| {de:e}");
        }
    }
}

/// Expected: a step far too large gives a typed error — `StepTooLarge` (before running, or when
/// SDIRK2's Newton iteration fails), `Diverged` (energy check, projection failure, state out of
/// bounds) or `ErrorEstimateExceeded` (the global error estimate over max_error) — never Ok, NaN or a panic: the pendulum with RK4 at dt = 0.5 s and SIE at 0.2 s, the
/// fourbar with RK4 at dt = 0.2 s, the stiff chain with SIE at dt = 0.01 s, the pendulum with
/// SDIRK2 at dt = 2 s.
#[test]
fn a_step_far_too_large_is_a_typed_error() {
    let cases = [
        ("params/pendulum_a01.yaml", Method::Rk4, 0.5),
        ("params/pendulum_a01.yaml", Method::SemiImplicitEuler, 0.2),
        ("params/fourbar.yaml", Method::Rk4, 0.2),
        (
            "params/report/spring_chain_stiff.yaml",
            Method::SemiImplicitEuler,
            0.01,
        ),
        ("params/pendulum_a01.yaml", Method::Sdirk2, 2.0),
    ];
    for (rel, method, dt) in cases {
        let sc = scene(rel);
        let mut p = predictor_with(&sc, method, dt, DriftControl::Projection, |s| {
            s.sample_period = dt;
        });
        let result = p.predict(&from_start(&sc, 40.0 * dt));
        match result {
            Err(
                e @ (Error::StepTooLarge { .. }
                | Error::Diverged { .. }
                | Error::ErrorEstimateExceeded { .. }),
            ) => {
                println!("{rel} {method:?} dt {dt}: {e}")
            }
            Err(e) => panic!("{rel} {method:?} dt {dt}: unexpected error {e}"),
            Ok(t) => panic!(
                "{rel} {method:?} dt {dt}: silently returned {} samples, last q {:?}",
                t.samples.len(),
                t.samples.last().unwrap().q
            ),
        }
    }
}
