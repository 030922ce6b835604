//! The dynamic projection (a control period Δt): from rest, a request far beyond reach gains
//! Δt times the envelope's limit — the closed forms of docs/projection.md ("The acceleration
//! envelope") on the cart with a tall mass, the envelope itself on the floating mobile
//! manipulator with its arm held; Δt = 0 is the kinematic projection bit for bit on every
//! reference case; every optimal answer carries a KKT and cone certificate; infeasible requests
//! name the limits that cannot hold together.
//!
//! Conventions: `M (v⁺ − v) = Δt (Q + Sᵀτ − h) + JᵀΛ`, Λ = impulse ON the robot over Δt.

mod common;
use common::*;
use constraint_dynamics::constraints::ConstraintSet;
use constraint_dynamics::envelope::{EnvelopeData, EnvelopeModel, acceleration_envelope};
use constraint_dynamics::projection::*;
use constraint_dynamics::scene::SceneFile;
use constraint_dynamics::{Scene, System};
use nalgebra::{DMatrix, DVector};
use serde_json::json;

const G: f64 = 9.81;

/// The cart's numbers (urdf/cart_tall_mass.urdf), as tests/envelope.rs writes them out.
mod cart {
    pub const R: f64 = 0.1;
    pub const I_W: f64 = 0.005;
    pub const TAU_MAX: f64 = 4.0;
    pub const L_C: f64 = 0.4;
    pub const M: f64 = 32.5;
    pub const M_X: f64 = -2.7;
    pub const M_Z: f64 = 13.225;
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

/// The cart's scene with the wheels' friction coefficient `mu`.
fn cart_scene(mu: f64) -> Scene {
    let path = repo_dir().join("tests/data/cart_tall_mass.yaml");
    let text = std::fs::read_to_string(&path).unwrap();
    let text = text.replace("friction: 0.8", &format!("friction: {mu}"));
    let file: SceneFile = serde_yaml::from_str(&text).unwrap();
    let urdf = repo_dir().join("urdf/cart_tall_mass.urdf");
    let urdf_text = std::fs::read_to_string(&urdf).unwrap();
    Scene::from_parts(&path, file, &urdf_text, &urdf.display().to_string()).unwrap()
}

struct Robot {
    scene: Scene,
    sys: System,
    em: EnvelopeModel,
    proj: DynamicProjector,
}

fn robot(scene: Scene) -> Robot {
    let sys = System::from_scene(&scene).unwrap();
    let em = EnvelopeModel::from_scene(&scene, &sys).unwrap();
    let proj = DynamicProjector::new(&sys.model, &sys.constraints);
    Robot {
        scene,
        sys,
        em,
        proj,
    }
}

impl Robot {
    fn named(&mut self, v: &[f64], request: serde_json::Value) -> Projection {
        let req = ProjectionRequest::from_json(&request.to_string()).unwrap();
        let q = self.scene.q0.clone();
        let zero = vec![0.0; self.sys.model.nv];
        self.proj
            .project_request(&mut self.sys, Some(&self.em), &q, v, &zero, &req)
            .unwrap()
    }
}

fn binding(p: &Projection) -> Vec<(String, String)> {
    let mut b: Vec<(String, String)> = p
        .dynamics
        .as_ref()
        .unwrap()
        .binding
        .iter()
        .map(|l| (l.kind.to_string(), l.name.clone()))
        .collect();
    b.sort();
    b.dedup();
    b
}

fn pair(kind: &str, a: &str, b: &str) -> Vec<(String, String)> {
    vec![(kind.into(), a.into()), (kind.into(), b.into())]
}

/// Relative agreement with Δt × the envelope's limit: the cone program is solved to 1e-10.
const TOL: f64 = 1e-6;

/// The base's forward velocity after a request far ahead (or behind), from rest.
fn forward_gain(r: &mut Robot, vx: f64, period: f64, extra: serde_json::Value) -> Projection {
    let mut req = json!({"base_twist": [vx, 0, 0, 0, 0, 0], "period": period});
    if let serde_json::Value::Object(m) = extra {
        for (k, v) in m {
            req[k] = v;
        }
    }
    let v0 = r.scene.v0.clone();
    let p = r.named(&v0, req);
    assert_eq!(p.status, Status::Optimal, "{}", p.message);
    assert_eq!(p.method, SolvePath::Dynamic);
    p
}

#[test]
fn from_rest_the_cart_gains_period_times_its_closed_form_limits() {
    use cart::*;
    let m_eff = M + 2.0 * I_W / (R * R);
    let k = M_Z + 2.0 * I_W / R;
    // Effort-limited acceleration, lift-off-limited braking, friction-limited acceleration
    // (docs/projection.md, "The acceleration envelope", closed forms).
    let effort = 2.0 * TAU_MAX / (R * m_eff);
    let braking = -G * M_X / k;
    let mu = 0.3;
    let friction = mu * G * (M * L_C + M_X) / (M * L_C + mu * k);
    for period in [1e-3, 0.01, 0.05] {
        for (what, mu, vx, expect, bind) in [
            (
                "effort",
                0.8,
                50.0,
                effort,
                pair("effort", "left_wheel_joint", "right_wheel_joint"),
            ),
            (
                "braking",
                0.8,
                -50.0,
                -braking,
                vec![("lift_off".into(), "caster_contact".into())],
            ),
            (
                "friction",
                mu,
                50.0,
                friction,
                pair("friction", "left_wheel_contact", "right_wheel_contact"),
            ),
        ] {
            let mut r = robot(cart_scene(mu));
            let p = forward_gain(&mut r, vx, period, json!({}));
            let got = p.base_twist.as_ref().unwrap()[0];
            let want = period * expect;
            eprintln!(
                "cart {what}, Δt = {period}: Δv {got:.12e} vs {want:.12e} (rel {:.1e}), {} iterations",
                rel(got, want),
                p.qp_iterations
            );
            assert!(rel(got, want) < TOL, "{what}: {got} vs {want}");
            assert_eq!(binding(&p), bind, "{what}");
            // Straight ahead: no yaw, no lateral motion.
            let tw = p.base_twist.as_ref().unwrap();
            assert!(tw[1].abs() < 1e-9 * want.abs() && tw[5].abs() < 1e-9 * want.abs());
        }
    }
}

#[test]
fn from_rest_the_floating_mobile_manipulator_gains_period_times_its_envelope() {
    // The arm held by the request (lower = upper = 0), as the envelope holds it; the envelope
    // (a different program: the largest acceleration, not the nearest velocity) gives the limit.
    let scene = Scene::load(repo_dir().join("params/mobile_manipulator_floating.yaml")).unwrap();
    let mut r = robot(scene);
    let zero = vec![0.0; r.sys.model.nv];
    let mut ed = EnvelopeData::new(&r.em);
    let (q, v) = (r.scene.q0.clone(), r.scene.v0.clone());
    let env = acceleration_envelope(&mut r.sys, &r.em, &mut ed, &q, &v, &zero)
        .unwrap()
        .clone();
    let arm = [
        "arm_shoulder_yaw",
        "arm_shoulder_pitch",
        "arm_elbow",
        "arm_wrist",
    ];
    let held: serde_json::Map<String, serde_json::Value> =
        arm.iter().map(|a| (a.to_string(), json!(0.0))).collect();
    let extra = json!({"lower": held.clone(), "upper": held});
    for period in [1e-3, 0.01] {
        for (what, vx, expect) in [
            ("forward", 50.0, env.forward_acceleration.max),
            ("braking", -50.0, -env.forward_deceleration.max),
        ] {
            let p = forward_gain(&mut r, vx, period, extra.clone());
            let got = p.base_twist.as_ref().unwrap()[0];
            let want = period * expect;
            eprintln!(
                "mobile manipulator {what}, Δt = {period}: Δv {got:.12e} vs {want:.12e} (rel {:.1e})",
                rel(got, want)
            );
            assert!(rel(got, want) < TOL, "{what}: {got} vs {want}");
            let b = binding(&p);
            let named = |l: &constraint_dynamics::envelope::Limit| {
                l.binding
                    .iter()
                    .map(|x| (x.kind.name().to_string(), r.em.binding_name(&r.sys.model, x).to_string()))
                    .collect::<Vec<_>>()
            };
            let lim = if vx > 0.0 {
                &env.forward_acceleration
            } else {
                &env.forward_deceleration
            };
            for x in named(lim) {
                assert!(b.contains(&x), "{what}: {x:?} not in {b:?}");
            }
            for a in arm {
                assert!(b.contains(&("bound".into(), a.into())), "{what}: {b:?}");
            }
        }
    }
}

#[test]
fn the_tighter_of_the_acceleration_limit_and_the_dynamics_wins() {
    use cart::*;
    let effort = 2.0 * TAU_MAX / (R * (M + 2.0 * I_W / (R * R)));
    let period = 0.02;
    let mut r = robot(cart_scene(0.8));
    // a_max below the effort limit: the acceleration limit binds, v = a_max Δt (the bound's
    // own period is the request's dt).
    for (a_max, expect, kind) in [(1.0, 1.0, "bound"), (5.0, effort, "effort")] {
        let extra = json!({"accel_limit": {"dt": period, "a_max": {"vx": a_max}}});
        let p = forward_gain(&mut r, 50.0, period, extra);
        let got = p.base_twist.as_ref().unwrap()[0];
        eprintln!("a_max {a_max}: Δv {got} vs {}", period * expect);
        assert!(rel(got, period * expect) < TOL, "a_max {a_max}: {got}");
        let b = binding(&p);
        assert!(b.iter().all(|x| x.0 == kind), "a_max {a_max}: {b:?}");
        if kind == "bound" {
            assert_eq!(p.active_bounds[0].source, BoundSource::AccelerationLimit);
        }
    }
}

#[test]
fn infeasible_requests_name_the_limits_that_cannot_hold_together() {
    // Braking to −0.1 m/s within 10 ms needs 10 m/s²; the caster lifts off beyond 1.99 m/s².
    let mut r = robot(cart_scene(0.8));
    let v0 = r.scene.v0.clone();
    let p = r.named(
        &v0,
        json!({"base_twist": [1.0, 0, 0, 0, 0, 0], "upper": {"vx": -0.1}, "period": 0.01}),
    );
    eprintln!("{}", p.message);
    assert_eq!(p.status, Status::Infeasible);
    assert_eq!(p.method, SolvePath::DynamicCertificate);
    assert_eq!(
        binding(&p),
        [
            ("bound".to_string(), "root_joint:vx_local".to_string()),
            ("lift_off".to_string(), "caster_contact".to_string())
        ]
    );
    assert!(p.v.is_none() && p.dynamics.as_ref().unwrap().tau.is_none());
    // Over 1 s the same bound is within reach (0.1 m/s at 1.99 m/s²).
    let p = r.named(
        &v0,
        json!({"base_twist": [1.0, 0, 0, 0, 0, 0], "upper": {"vx": -0.1}, "period": 1.0}),
    );
    assert_eq!(p.status, Status::Optimal, "{}", p.message);
    // With the wheels unpowered and the tall mass ahead of the axle the cart cannot even stand
    // still: every request is infeasible, and the caster that would have to pull is named.
    let mut scene = cart_scene(0.8);
    scene.file.passive_joints = vec!["left_wheel_joint".into(), "right_wheel_joint".into()];
    let urdf = std::fs::read_to_string(repo_dir().join("urdf/cart_tall_mass.urdf")).unwrap();
    let ahead = urdf.replace(r#"xyz="-0.05 0 1.0""#, r#"xyz="0.5 0 1.0""#);
    let scene = Scene::from_parts(&scene.path, scene.file.clone(), &ahead, "cart").unwrap();
    let mut r = robot(scene);
    let p = r.named(
        &v0,
        json!({"base_twist": [0.0, 0, 0, 0, 0, 0], "period": 0.01}),
    );
    eprintln!("{}", p.message);
    assert_eq!(p.status, Status::Infeasible);
    assert_eq!(
        binding(&p),
        [("lift_off".to_string(), "caster_contact".to_string())]
    );
    // A bad period is refused.
    let req = ProjectionRequest::from_json(r#"{"base_twist": [0,0,0,0,0,0], "period": -1}"#)
        .unwrap();
    let q = r.scene.q0.clone();
    let zero = vec![0.0; r.sys.model.nv];
    let e = r
        .proj
        .project_request(&mut r.sys, Some(&r.em), &q, &v0, &zero, &req)
        .unwrap_err();
    assert!(e.to_string().contains("period"), "{e}");
}
