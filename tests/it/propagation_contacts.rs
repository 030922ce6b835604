//! When ideal rolling breaks (predict/contacts.rs): a prediction with forces reports the first
//! sample and contact where the motion needs more friction than μ (`slip`) or a contact would
//! have to pull (`lift_off`), against closed forms written here from the URDF's numbers, and
//! against Coulomb's rule written out on the same sample's forces.
//!
//! The cart (tests/data/cart_torque_ramp.yaml, urdf/cart_tall_mass.urdf) is symmetric left to
//! right, on a flat floor, starting at rest; both wheels get the same torque τ(t) = k t. It
//! only translates (no pitch: the wheels' normal rows and the caster hold it; no yaw: the same
//! torque on both wheels), so at every instant, with f_t the ground's forward force on each
//! wheel and a the forward acceleration:
//!
//! ```text
//! cart:   M a = 2 f_t
//! wheel:  I_w a / r = τ − r f_t                      (rolling: spin acceleration a / r)
//!   ⇒     a(t) = 2 k t / (r m_eff),   m_eff = M + 2 I_w / r²,   f_t = M a / 2
//! caster: N_c(a) = (a K − g Σmx) / L_c,   K = Σmz + 2 I_w / r     (moments about the axle
//!                                                                   line; tests/it/envelope.rs)
//! wheel:  N_w(a) = (M g − N_c(a)) / 2
//! ```
//!
//! Slip when f_t = μ N_w: a* = μ g (M L_c + Σmx) / (M L_c + μ K), at t* = a* r m_eff / (2 k).
//! Lift-off of the caster when N_c = 0 (τ = −k t, the cart pushed backwards): a = g Σmx / K,
//! at t = |g Σmx / K| r m_eff / (2 k). The report names the first sample at or after the break,
//! so it lies within one sample period after the closed form.

use crate::common;

use common::repo_dir;
use constraint_dynamics::actuators::Command;
use constraint_dynamics::constraints::{BreakKind, ContactLimits};
use constraint_dynamics::predict::{PredictionRequest, Predictor, Trajectory};
use constraint_dynamics::scene::SceneFile;
use constraint_dynamics::{Scene, System};

const G: f64 = 9.81;

/// urdf/cart_tall_mass.urdf: wheel radius, wheel spin inertia, caster distance behind the axle,
/// total mass, Σ m x and Σ m z over every body (wheels included), as tests/it/envelope.rs writes
/// them out.
const R: f64 = 0.1;
const I_W: f64 = 0.005;
const L_C: f64 = 0.4;
const M: f64 = 32.5;
const M_X: f64 = -2.7;
const M_Z: f64 = 13.225;
/// The wheels' μ in the scene.
const MU: f64 = 0.8;
/// Torque ramp rate k [N·m/s] of the scene's `joint_torques` profile (0 → 10 N·m over 1 s).
const K_RAMP: f64 = 10.0;
/// Agreement of λ with the closed forms, relative to the force in question (the friction used,
/// the weight): λ solves the constrained dynamics to rounding (achieved up to 2.4e-15 below).
const TOL: f64 = 1e-13;
/// Sample period of the scene [s].
const SAMPLE: f64 = 0.01;

fn m_eff() -> f64 {
    M + 2.0 * I_W / (R * R)
}

fn k_pitch() -> f64 {
    M_Z + 2.0 * I_W / R
}

/// Forward acceleration under τ = k t (k signed) [m/s²].
fn accel(k: f64, t: f64) -> f64 {
    2.0 * k * t / (R * m_eff())
}

/// Each wheel's normal force at forward acceleration a [N].
fn wheel_normal(a: f64) -> f64 {
    let caster = (a * k_pitch() - G * M_X) / L_C;
    (M * G - caster) / 2.0
}

/// The scene with the torque ramp's rate multiplied by `sign` (±1).
fn ramp_scene(sign: f64) -> Scene {
    let path = repo_dir().join("tests/data/cart_torque_ramp.yaml");
    let text = std::fs::read_to_string(&path).unwrap();
    let ramp = "[1.0, 10.0]";
    assert_eq!(text.matches(ramp).count(), 2);
    let text = text.replace(ramp, &format!("[1.0, {}]", sign * K_RAMP));
    let file: SceneFile = serde_yaml::from_str(&text).unwrap();
    let urdf = repo_dir().join("urdf/cart_tall_mass.urdf");
    let urdf_text = std::fs::read_to_string(&urdf).unwrap();
    Scene::from_parts(&path, file, &urdf_text, &urdf.display().to_string()).unwrap()
}

fn predict(scene: &Scene, forces: bool) -> Trajectory {
    let mut p = Predictor::from_scene(scene).unwrap();
    p.predict(&PredictionRequest::new(&scene.q0, &scene.v0).forces(forces))
        .unwrap()
}

/// The sample at time t of `traj`.
fn sample_at(traj: &Trajectory, t: f64) -> usize {
    traj.samples.iter().position(|s| s.t == t).unwrap()
}

#[test]
fn a_torque_ramp_slips_the_wheels_when_the_closed_form_says() {
    let a_star = MU * G * (M * L_C + M_X) / (M * L_C + MU * k_pitch());
    let t_star = a_star * R * m_eff() / (2.0 * K_RAMP);
    let scene = ramp_scene(1.0);
    let traj = predict(&scene, true);
    let check = traj.contact_check.as_ref().unwrap();
    assert_eq!(
        check.contacts,
        [
            "left_wheel_contact",
            "right_wheel_contact",
            "caster_contact"
        ]
    );
    // Every contact declares what its judgement needs: μ on the wheels, a normal row on all.
    assert!(check.unchecked.is_empty(), "{:?}", check.unchecked);
    let b = traj
        .first_contact_break()
        .expect("a slip within the horizon");
    eprintln!(
        "slip: closed form t* = {t_star:.6} s, reported {} s on {} (friction used {:.6}), \
         sample period {SAMPLE} s",
        b.t,
        b.contact,
        b.friction_used.unwrap()
    );
    assert_eq!(b.kind, BreakKind::Slip);
    assert!(
        b.t >= t_star && b.t - t_star <= SAMPLE,
        "reported {} s, closed form {t_star} s",
        b.t
    );
    // Friction used at the reported sample: (M a / 2) / (μ N_w(a)), a = a(t); and N_w(a).
    let a = accel(K_RAMP, b.t);
    let used = (M * a / 2.0) / (MU * wheel_normal(a));
    let got = b.friction_used.unwrap();
    let err_used = (got - used).abs() / used;
    let err_n = (b.normal_force - wheel_normal(a)).abs() / (M * G);
    eprintln!(
        "friction used at the break: {got} vs {used} (rel {err_used:.1e}); N_w rel {err_n:.1e}"
    );
    assert!(
        err_used < TOL && err_n < TOL,
        "{got} vs {used}; N {}",
        b.normal_force
    );
    // Coulomb's rule |f_t| > μ N on the same sample's forces flags the same contact at that
    // sample and not at the one before.
    let k = sample_at(&traj, b.t);
    let judged = |i: usize| {
        let forces = traj.samples[i].forces.as_ref().unwrap();
        let f = forces.iter().find(|f| f.name == b.contact).unwrap();
        f.tangential_force.unwrap() > MU * f.normal_force.unwrap()
    };
    assert!(judged(k) && !judged(k - 1));
    // Per sample: the caster has no friction to judge; both wheels use the same share.
    let states = traj.samples[k].contacts.as_ref().unwrap();
    assert_eq!(states[2].friction_used, None);
    assert!(states[2].normal_force.unwrap() > 0.0);
    let (l, r) = (
        states[0].friction_used.unwrap(),
        states[1].friction_used.unwrap(),
    );
    eprintln!("left − right friction used: {:.1e}", (l - r).abs());
    assert!((l - r).abs() < TOL * l);
}

#[test]
fn pushing_the_cart_backwards_lifts_the_caster_when_the_closed_form_says() {
    let a_lift = G * M_X / k_pitch();
    let t_lift = a_lift.abs() * R * m_eff() / (2.0 * K_RAMP);
    let traj = predict(&ramp_scene(-1.0), true);
    let b = traj
        .first_contact_break()
        .expect("a lift-off within the horizon");
    eprintln!(
        "lift-off: closed form t = {t_lift:.6} s, reported {} s on {} (N = {:.4} N), sample \
         period {SAMPLE} s",
        b.t, b.contact, b.normal_force
    );
    assert_eq!(
        (b.kind, b.contact.as_str()),
        (BreakKind::LiftOff, "caster_contact")
    );
    assert!(
        b.t >= t_lift && b.t - t_lift <= SAMPLE,
        "reported {} s, closed form {t_lift} s",
        b.t
    );
    // The pull it would need: N_c(a(t)) < 0.
    let a = accel(-K_RAMP, b.t);
    let n_c = (a * k_pitch() - G * M_X) / L_C;
    let err = (b.normal_force - n_c).abs() / (M * G);
    eprintln!(
        "caster pull: {} N vs {n_c} N (rel to the weight {err:.1e})",
        b.normal_force
    );
    assert!(n_c < 0.0 && err < TOL);
    assert_eq!(b.friction_used, None);
}

#[test]
fn the_judgement_changes_no_answer_and_costs_nothing_without_forces() {
    let scene = ramp_scene(1.0);
    let with = predict(&scene, true);
    let without = predict(&scene, false);
    assert!(without.contact_check.is_none() && without.first_contact_break().is_none());
    assert_eq!(with.samples.len(), without.samples.len());
    for (a, b) in with.samples.iter().zip(&without.samples) {
        assert!(a.q == b.q && a.v == b.v && b.contacts.is_none());
    }
}

#[test]
fn assumed_friction_applies_only_where_a_contact_declares_none() {
    // The scene's μ wins over an assumed one; the caster (no tangential rows) stays unjudged.
    let scene = ramp_scene(1.0);
    let mut p = Predictor::from_scene(&scene).unwrap();
    let limits = ContactLimits {
        friction: Some(0.01),
        normal_force: Some(1.0),
    };
    let req = PredictionRequest::new(&scene.q0, &scene.v0)
        .forces(true)
        .contact_limits(limits);
    let traj = p.predict(&req).unwrap();
    let plain = predict(&scene, true);
    assert_eq!(traj.contact_check, plain.contact_check);
    // Non-finite or negative assumptions are refused, naming the field.
    for (bad, field) in [
        (
            ContactLimits {
                friction: Some(-0.1),
                ..limits
            },
            "contact_limits.friction",
        ),
        (
            ContactLimits {
                normal_force: Some(f64::NAN),
                ..limits
            },
            "contact_limits.normal_force",
        ),
    ] {
        let e = p.predict(&req.contact_limits(bad)).unwrap_err().to_string();
        assert!(e.contains(field), "{e}");
    }
}

#[test]
fn a_planar_base_lists_its_wheels_unchecked_unless_the_caller_assumes_their_limits() {
    // params/suite_diff_drive.yaml: planar base (no normal rows), wheels without `friction:`.
    // Commanded (0.5 m/s, 0.4 rad/s) from rest, both wheels saturate at 5 N·m
    // (tests/it/propagation_actuator_forces.rs): about 100 N of tangential force each against the
    // ~36 N a μ = 0.8 grip on half the weight gives, a slip from the first sample on.
    let scene = Scene::load(repo_dir().join("params/suite_diff_drive.yaml")).unwrap();
    let mut p = Predictor::from_scene(&scene).unwrap();
    let cmd = [(
        0.0,
        Command {
            base_twist: Some([0.5, 0.4]),
            ..Default::default()
        },
    )];
    let req = PredictionRequest::new(&scene.q0, &scene.v0)
        .commands(&cmd)
        .horizon(0.1)
        .forces(true);
    // Nothing assumed: lift-off and friction of both wheels unchecked, no break reported.
    let traj = p.predict(&req).unwrap();
    let check = traj.contact_check.as_ref().unwrap();
    let unchecked: Vec<_> = check
        .unchecked
        .iter()
        .map(|u| (u.kind, u.name.as_str()))
        .collect();
    assert_eq!(
        unchecked,
        [
            ("lift_off", "left_wheel_contact"),
            ("friction", "left_wheel_contact"),
            ("lift_off", "right_wheel_contact"),
            ("friction", "right_wheel_contact"),
        ]
    );
    assert!(check.first_break.is_none());
    // The nodes' rule (μ = 0.8, N = m·|g| / 2 with urdf/diff_drive.urdf's m = 8 + 2 × 0.5 +
    // 0.2 kg): friction judged, lift-off still not, and every sample's verdict is Coulomb's.
    let sys = System::from_scene(&scene).unwrap();
    let limits = ContactLimits::assumed(sys.model(), sys.constraints(), 0.8, 0.0);
    let weight_share = 9.2 * G / 2.0;
    let n = limits.normal_force.unwrap();
    assert!((n - weight_share).abs() <= 1e-14 * weight_share, "{n}");
    assert_eq!(limits.friction, Some(0.8));
    let given = ContactLimits::assumed(sys.model(), sys.constraints(), 0.8, 30.0);
    assert_eq!(
        given.normal_force,
        Some(30.0),
        "a positive planar normal force wins"
    );
    let traj = p.predict(&req.contact_limits(limits)).unwrap();
    let check = traj.contact_check.as_ref().unwrap();
    let lift_off_only = check.unchecked.iter().all(|u| u.kind == "lift_off");
    assert!(lift_off_only && check.unchecked.len() == 2);
    let b = traj.first_contact_break().unwrap();
    assert_eq!((b.t, b.kind), (0.0, BreakKind::Slip));
    for s in &traj.samples {
        let states = s.contacts.as_ref().unwrap();
        for (state, name) in states.iter().zip(&check.contacts) {
            let forces = s.forces.as_ref().unwrap();
            let f = forces.iter().find(|f| &f.name == name).unwrap();
            let slipping = f.tangential_force.unwrap() > 0.8 * n;
            assert_eq!(state.breaks.is_some(), slipping);
            assert_eq!(state.normal_force, Some(n));
        }
    }
}
