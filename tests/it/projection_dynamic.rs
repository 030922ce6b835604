//! The dynamic projection (a control period Δt): from rest, a request far beyond reach gains
//! Δt times the envelope's limit — the closed forms of docs/projection.md ("The acceleration
//! envelope") on the cart with a tall mass, the envelope itself on the floating mobile
//! manipulator with its arm held; Δt = 0 is the kinematic projection bit for bit on every
//! reference case; infeasible requests name the limits that cannot hold together. Every
//! optimal answer's KKT and cone certificate is `projection_dynamic_certificates`.
//!
//! Conventions: `M (v⁺ − v) = Δt (Q + Sᵀτ − h) + JᵀΛ`, Λ = impulse ON the robot over Δt.

use crate::common;
use common::*;
use constraint_dynamics::constraints::ConstraintSet;
use constraint_dynamics::envelope::{EnvelopeData, EnvelopeModel, acceleration_envelope};
use constraint_dynamics::projection::*;
use constraint_dynamics::scene::SceneFile;
use constraint_dynamics::{Scene, System};
use serde_json::json;

const G: f64 = 9.81;

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

/// The cart's scene with the wheels' friction coefficient `mu`.
pub(crate) fn cart_scene(mu: f64) -> Scene {
    let path = repo_dir().join("tests/data/cart_tall_mass.yaml");
    let text = std::fs::read_to_string(&path).unwrap();
    let text = text.replace("friction: 0.8", &format!("friction: {mu}"));
    let file: SceneFile = serde_yaml::from_str(&text).unwrap();
    let urdf = repo_dir().join("urdf/cart_tall_mass.urdf");
    let urdf_text = std::fs::read_to_string(&urdf).unwrap();
    Scene::from_parts(&path, file, &urdf_text, &urdf.display().to_string()).unwrap()
}

pub(crate) struct Robot {
    pub(crate) scene: Scene,
    pub(crate) sys: System,
    pub(crate) em: EnvelopeModel,
    pub(crate) proj: DynamicProjector,
}

pub(crate) fn robot(scene: Scene) -> Robot {
    let sys = System::from_scene(&scene).unwrap();
    let em = EnvelopeModel::from_scene(&scene, &sys).unwrap();
    let proj = DynamicProjector::new(sys.model(), sys.constraints());
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
        let zero = vec![0.0; self.sys.model().nv];
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
    let zero = vec![0.0; r.sys.model().nv];
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
                    .map(|x| {
                        (
                            x.kind.name().to_string(),
                            r.em.binding_name(r.sys.model(), x).to_string(),
                        )
                    })
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
    let req =
        ProjectionRequest::from_json(r#"{"base_twist": [0,0,0,0,0,0], "period": -1}"#).unwrap();
    let q = r.scene.q0.clone();
    let zero = vec![0.0; r.sys.model().nv];
    let e = r
        .proj
        .project_request(&mut r.sys, Some(&r.em), &q, &v0, &zero, &req)
        .unwrap_err();
    assert!(e.to_string().contains("period"), "{e}");
}

// ---------------------------------------------------------------------------------------------
// Δt = 0: the kinematic projection, bit for bit.

/// Every reference case's problems (equality-only and bounded, as tests/it/projection.rs poses
/// them), the mobile manipulator's mixed problem and the diff drive's: Δt = 0 through the
/// dynamic projector equals a fresh kinematic projector exactly (achieved: 0, the same path).
#[test]
fn period_zero_is_the_kinematic_projection() {
    let mut worst = 0.0f64;
    let mut cases = 0;
    let mut compare = |tag: &str,
                       sys: &mut System,
                       em: Option<&EnvelopeModel>,
                       q: &[f64],
                       p: &ProjectionProblem| {
        let nv = sys.model().nv;
        let zero = vec![0.0; nv];
        let mut dynamic = DynamicProjector::new(sys.model(), sys.constraints());
        let od = dynamic.project(sys, em, q, &zero, &zero, p, 0.0).unwrap();
        let mut kin = VelocityProjector::new(sys.model(), sys.constraints());
        let ok = kin
            .project(
                sys.model(),
                &mut constraint_dynamics::algorithm::Data::new(sys.model()),
                sys.constraints(),
                &mut constraint_dynamics::constraints::ConstraintData::new(
                    sys.model(),
                    sys.constraints(),
                ),
                q,
                p,
            )
            .unwrap();
        assert_eq!(od, ok, "{tag}");
        let d = &dynamic.kinematic;
        for (what, a, b) in [
            ("v", d.v.as_slice(), kin.v.as_slice()),
            ("lambda", d.lambda.as_slice(), kin.lambda.as_slice()),
            ("nu", d.nu.as_slice(), kin.nu.as_slice()),
        ] {
            let e = rel_err(a, b);
            worst = worst.max(if e.is_nan() { 0.0 } else { e });
            assert!(
                e <= 1e-12 || (a.iter().all(|x| x.is_nan()) && b.iter().all(|x| x.is_nan())),
                "{tag} {what}: {e}"
            );
            assert!(
                a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits()),
                "{tag} {what}: not bit for bit"
            );
        }
        cases += 1;
    };
    let bound_array = |v: &serde_json::Value, none: f64| -> Vec<f64> {
        v.as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap_or(none))
            .collect()
    };
    for name in [
        "fourbar",
        "ur5_ee_point",
        "solo12_four_feet",
        "rolling_disk",
    ] {
        let case = load_case(name);
        let model = case_model(&case);
        for (k, st) in case["states"].as_array().unwrap().iter().enumerate() {
            let q = vecf(&st["q"]);
            let set = ConstraintSet::new(&model, &specs_for(&case, st), &q).unwrap();
            let mut sys = System::new(model.clone(), set, Default::default(), Default::default());
            let vp = &st["expected"]["velocity_projection"];
            let mut p = ProjectionProblem::new(&model);
            p.velocity_limits = false;
            p.v_des = vecf(&vp["v_des"]);
            compare(
                &format!("{name}[{k}] equality-only"),
                &mut sys,
                None,
                &q,
                &p,
            );
            if let Some(b) = vp.get("bounded") {
                p.lower = bound_array(&b["lb"], f64::NEG_INFINITY);
                p.upper = bound_array(&b["ub"], f64::INFINITY);
                compare(&format!("{name}[{k}] bounded"), &mut sys, None, &q, &p);
            }
        }
    }
    for name in [
        "mobile_manipulator.yaml",
        "diff_drive.yaml",
        "mobile_manipulator_floating.yaml",
    ] {
        let (scene, mut sys) = scene_system(name);
        let em = EnvelopeModel::from_scene(&scene, &sys).unwrap();
        let nv = sys.model().nv;
        let mut p = ProjectionProblem::new(sys.model());
        p.v_des = (0..nv)
            .map(|i| 3.0 * ((i as f64 + 1.0) * 0.7).sin())
            .collect();
        compare(
            &format!("{name} URDF limits"),
            &mut sys,
            Some(&em),
            &scene.q0,
            &p,
        );
        p.upper[0] = 0.1;
        p.accel_limit = Some(AccelLimit {
            dt: 0.1,
            a_max: vec![1.0; nv],
            v_current: scene.v0.clone(),
        });
        compare(
            &format!("{name} bounded"),
            &mut sys,
            Some(&em),
            &scene.q0,
            &p,
        );
        // The named path: the same JSON.
        let req =
            ProjectionRequest::from_json(r#"{"base_twist": [0.5, 0.0, 0.3], "mode": "mass"}"#);
        let req = match (req, sys.model().base) {
            (Ok(r), constraint_dynamics::model::BaseType::Planar) => r,
            _ => ProjectionRequest::from_json(
                r#"{"base_twist": [0.5, 0, 0, 0, 0, 0.3], "upper": {"vx": 0.2}}"#,
            )
            .unwrap(),
        };
        let zero = vec![0.0; nv];
        let mut dynamic = DynamicProjector::new(sys.model(), sys.constraints());
        let a = dynamic
            .project_request(&mut sys, Some(&em), &scene.q0, &scene.v0, &zero, &req)
            .unwrap();
        let mut kin = VelocityProjector::new(sys.model(), sys.constraints());
        let b = project_system(&mut kin, &mut sys, &scene.q0, &scene.v0, &req).unwrap();
        assert_eq!(
            serde_json::to_string(&a).unwrap(),
            serde_json::to_string(&b).unwrap(),
            "{name}: named"
        );
        assert!(a.dynamics.is_none());
    }
    eprintln!("Δt = 0 on {cases} problems: largest relative difference {worst:e}");
}
