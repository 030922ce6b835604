//! The acceleration envelope against closed forms derived by hand in docs/projection.md ("The
//! acceleration envelope"), from the URDFs' numbers written out here (never from the code):
//! the cart with a tall mass (tests/data/cart_tall_mass.yaml, floating base, unilateral caster) and
//! the planar differential drive (params/diff_drive.yaml).

use crate::common;

use common::{cart, repo_dir};
use constraint_dynamics::envelope::{
    BindingKind, Contact, EnvelopeData, EnvelopeModel, EnvelopeReport, Reach, acceleration_envelope,
};
use constraint_dynamics::scene::SceneFile;
use constraint_dynamics::{Scene, System};

/// Relative agreement with the closed forms: the cone program is solved to 1e-10 (gap and
/// feasibility), so the limits agree to well below this.
const TOL: f64 = 1e-6;

const G: f64 = 9.81;

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

/// The cart's scene with the wheels' friction coefficient `mu`.
fn cart_scene(mu: f64) -> Scene {
    let path = repo_dir().join("tests/data/cart_tall_mass.yaml");
    let text = std::fs::read_to_string(&path).unwrap();
    assert_eq!(text.matches("friction: 0.8").count(), 2);
    let text = text.replace("friction: 0.8", &format!("friction: {mu}"));
    let file: SceneFile = serde_yaml::from_str(&text).unwrap();
    let urdf = repo_dir().join("urdf/cart_tall_mass.urdf");
    let urdf_text = std::fs::read_to_string(&urdf).unwrap();
    Scene::from_parts(&path, file, &urdf_text, &urdf.display().to_string()).unwrap()
}

/// The envelope of `scene` at its initial state, named.
fn envelope_of(scene: &Scene) -> (System, EnvelopeModel, EnvelopeData, EnvelopeReport) {
    let mut sys = System::from_scene(scene).unwrap();
    let em = EnvelopeModel::from_scene(scene, &sys).unwrap();
    let mut ed = EnvelopeData::new(&em);
    let zero = vec![0.0; sys.model().nv];
    acceleration_envelope(&mut sys, &em, &mut ed, &scene.q0, &scene.v0, &zero).unwrap();
    let report = EnvelopeReport::new(sys.model(), &em, &ed.envelope);
    let e = &ed.envelope;
    eprintln!(
        "iterations: {} {} {} {}",
        e.forward_acceleration.iterations,
        e.forward_deceleration.iterations,
        e.yaw_acceleration_left.iterations,
        e.yaw_acceleration_right.iterations
    );
    (sys, em, ed, report)
}

fn names(report: &constraint_dynamics::envelope::LimitReport) -> Vec<(String, String)> {
    let mut v: Vec<_> = report
        .binding
        .iter()
        .map(|b| (b.kind.to_string(), b.name.clone()))
        .collect();
    v.sort();
    v
}

fn pair(kind: &str, a: &str, b: &str) -> Vec<(String, String)> {
    vec![(kind.into(), a.into()), (kind.into(), b.into())]
}

#[test]
fn cart_forward_acceleration_is_limited_by_the_wheels_effort() {
    use cart::*;
    // a = 2 τ_max / (r m_eff), m_eff = M + 2 I_w / r².
    let m_eff = M + 2.0 * I_W / (R * R);
    let expect = 2.0 * TAU_MAX / (R * m_eff);
    let (_, _, ed, report) = envelope_of(&cart_scene(0.8));
    let got = report.forward_acceleration.max.unwrap();
    eprintln!(
        "effort-limited a: {got} vs {expect} (rel {:.2e})",
        rel(got, expect)
    );
    assert!(rel(got, expect) < TOL, "{got} vs {expect}");
    assert_eq!(
        names(&report.forward_acceleration),
        pair("effort", "left_wheel_joint", "right_wheel_joint")
    );
    assert!(report.unchecked.is_empty(), "{:?}", report.unchecked);
    // The optimum holds the yaw acceleration at zero and drives both wheels at +τ_max.
    let lim = &ed.envelope.forward_acceleration;
    assert!(lim.qdd[5].abs() < 1e-9 && (lim.tau[0] - TAU_MAX).abs() < 1e-6 * TAU_MAX);
}

#[test]
fn cart_forward_acceleration_is_limited_by_friction_with_a_low_mu() {
    use cart::*;
    // M a = μ (M g − N_c(a)), N_c(a) = (a K − g Σmx)/L_c, K = Σmz + 2 I_w/r:
    // a = μ g (M L_c + Σmx) / (M L_c + μ K).
    let mu = 0.3;
    let k = M_Z + 2.0 * I_W / R;
    let expect = mu * G * (M * L_C + M_X) / (M * L_C + mu * k);
    let effort_limit = 2.0 * TAU_MAX / (R * (M + 2.0 * I_W / (R * R)));
    assert!(expect < effort_limit);
    let (_, _, ed, report) = envelope_of(&cart_scene(mu));
    let got = report.forward_acceleration.max.unwrap();
    eprintln!(
        "friction-limited a: {got} vs {expect} (rel {:.2e})",
        rel(got, expect)
    );
    assert!(rel(got, expect) < TOL, "{got} vs {expect}");
    assert_eq!(
        names(&report.forward_acceleration),
        pair("friction", "left_wheel_contact", "right_wheel_contact")
    );
    // Each wheel pushes forward with M a / 2 = μ N_w (rows t₁, t₂, n per wheel, then the caster).
    let lam = &ed.envelope.forward_acceleration.lambda;
    let n_w = (M * G - (expect * k - G * M_X) / L_C) / 2.0;
    assert!(rel(lam[0], M * expect / 2.0) < TOL && rel(lam[2], n_w) < TOL);
    assert!(rel(lam[6], (expect * k - G * M_X) / L_C) < TOL);
}

#[test]
fn cart_braking_is_limited_by_the_caster_lifting_off() {
    use cart::*;
    // N_c(a) = (a K − g Σmx)/L_c = 0 at a = g Σmx / K: the deceleration −a = g |Σmx| / K.
    let k = M_Z + 2.0 * I_W / R;
    let expect = -G * M_X / k;
    for mu in [0.8, 0.3] {
        let (_, _, ed, report) = envelope_of(&cart_scene(mu));
        let got = report.forward_deceleration.max.unwrap();
        eprintln!(
            "lift-off-limited braking (μ = {mu}): {got} vs {expect} (rel {:.2e})",
            rel(got, expect)
        );
        assert!(rel(got, expect) < TOL, "{got} vs {expect}");
        assert_eq!(
            names(&report.forward_deceleration),
            vec![("lift_off".to_string(), "caster_contact".to_string())]
        );
        let lim = &ed.envelope.forward_deceleration;
        assert!(
            lim.lambda[6].abs() < 1e-6 * M * G,
            "caster λ {}",
            lim.lambda[6]
        );
        // The wheels carry the whole weight and brake with M a / 2 each.
        assert!(rel(lim.lambda[2] + lim.lambda[5], M * G) < TOL);
        assert!(rel(lim.lambda[0], -M * expect / 2.0) < TOL);
    }
}

/// params/diff_drive.yaml (urdf/diff_drive.urdf): planar base, r = 0.05 m, half-track
/// d = 0.17 m, wheel spin inertia 0.000625 kg·m², effort 5 N·m.
#[test]
fn planar_diff_drive_yaw_acceleration_is_limited_by_effort() {
    let (r, d, i_w, tau) = (0.05, 0.17, 0.000625, 5.0);
    // Yaw inertia about the axle midpoint (vertical axis), each body's izz + m (x² + y²):
    // chassis 0.1666…7 + 8 × 0.05², wheels 2 × (0.00035 + 0.5 × 0.17²), caster 5e-5 + 0.2 × 0.15².
    let i_o = 0.166666666666667
        + 8.0 * 0.05f64.powi(2)
        + 2.0 * (0.00035 + 0.5 * d * d)
        + (5e-5 + 0.2 * 0.15f64.powi(2));
    // (I_O + 2 I_w d²/r²) α = (d/r)(τ_R − τ_L), τ_R = −τ_L = τ_max.
    let expect = 2.0 * tau * d / r / (i_o + 2.0 * i_w * d * d / (r * r));
    // Forward: a = 2 τ_max / (r (M + 2 I_w / r²)), M = 8 + 2 × 0.5 + 0.2.
    let expect_fwd = 2.0 * tau / (r * (9.2 + 2.0 * i_w / (r * r)));
    let scene = Scene::load(repo_dir().join("params/diff_drive.yaml")).unwrap();
    let (_, _, _, report) = envelope_of(&scene);
    for (what, lim, e) in [
        ("yaw left", &report.yaw_acceleration_left, expect),
        ("yaw right", &report.yaw_acceleration_right, expect),
        ("forward", &report.forward_acceleration, expect_fwd),
        ("braking", &report.forward_deceleration, expect_fwd),
    ] {
        let got = lim.max.unwrap();
        eprintln!("diff drive {what}: {got} vs {e} (rel {:.2e})", rel(got, e));
        assert!(rel(got, e) < TOL, "{what}: {got} vs {e}");
        assert_eq!(
            names(lim),
            pair("effort", "left_wheel_joint", "right_wheel_joint"),
            "{what}"
        );
    }
    // A planar base has no normal rows: lift-off and friction are listed, not guessed.
    let mut unchecked: Vec<_> = report
        .unchecked
        .iter()
        .map(|u| format!("{}:{}", u.kind, u.name))
        .collect();
    unchecked.sort();
    assert_eq!(
        unchecked,
        [
            "friction:left_wheel_contact",
            "friction:right_wheel_contact",
            "lift_off:left_wheel_contact",
            "lift_off:right_wheel_contact"
        ]
    );
}

#[test]
fn passive_wheels_unbounded_efforts_and_fixed_bases_are_reported() {
    // Both wheels passive: nothing drives the base, whose only acceleration with the yaw held
    // is a = 0 ((M + 2 I_w/r²) a = 0), so both forward limits are 0.
    let mut scene = cart_scene(0.8);
    scene.file.passive_joints = vec!["left_wheel_joint".into(), "right_wheel_joint".into()];
    let (_, _, _, report) = envelope_of(&scene);
    assert!(report.forward_acceleration.max.unwrap().abs() < 1e-6);
    assert!(report.forward_deceleration.max.unwrap().abs() < 1e-6);
    // The same with the tall mass 0.5 m ahead of the axle: standing still would need the caster
    // to pull (Σ m x = 20 × (−0.1) + 0.5 × (−0.4) + 10 × 0.5 > 0), and a = 0 is all the
    // unpowered cart can do: no limit is feasible.
    let urdf = std::fs::read_to_string(repo_dir().join("urdf/cart_tall_mass.urdf")).unwrap();
    let ahead = urdf.replace(r#"xyz="-0.05 0 1.0""#, r#"xyz="0.5 0 1.0""#);
    assert_ne!(ahead, urdf);
    let ahead = Scene::from_parts(&scene.path, scene.file.clone(), &ahead, "cart").unwrap();
    let (_, _, ed, report) = envelope_of(&ahead);
    assert_eq!(ed.envelope.forward_deceleration.reach, Reach::Infeasible);
    let json = serde_json::to_value(&report).unwrap();
    assert_eq!(json["forward_deceleration"]["infeasible"], true);
    assert!(json["forward_deceleration"].get("max").is_none());
    // The diff drive without `effort`: nothing bounds it (a planar base has no cones), and the
    // efforts are listed as unchecked.
    let path = repo_dir().join("params/diff_drive.yaml");
    let urdf = std::fs::read_to_string(repo_dir().join("urdf/diff_drive.urdf")).unwrap();
    let urdf = urdf.replace(r#"effort="5" "#, "");
    let file: SceneFile = serde_yaml::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    let scene = Scene::from_parts(&path, file, &urdf, "diff_drive.urdf").unwrap();
    let (_, _, ed, report) = envelope_of(&scene);
    assert_eq!(ed.envelope.yaw_acceleration_left.reach, Reach::Unbounded);
    let json = serde_json::to_value(&report).unwrap();
    assert_eq!(json["forward_acceleration"]["unbounded"], true);
    assert!(json["forward_acceleration"].get("max").is_none());
    assert!(
        report
            .unchecked
            .iter()
            .any(|u| u.kind == "effort" && u.name == "left_wheel_joint")
    );
    // A fixed base has no envelope.
    let fixed = Scene::load(repo_dir().join("params/fourbar.yaml")).unwrap();
    let sys = System::from_scene(&fixed).unwrap();
    let e = EnvelopeModel::from_scene(&fixed, &sys).unwrap_err();
    assert!(e.to_string().contains("fixed-base"), "{e}");
}

#[test]
fn braking_limit_of_the_floating_mobile_manipulator_falls_as_the_arm_leans_forward() {
    // The arm's centre of mass moves forward with the shoulder pitch (a positive pitch leans the
    // arm forward, urdf/mobile_manipulator.urdf); the caster behind the axle unloads, so the
    // largest deceleration before it lifts off falls, and once the centre of mass is ahead of
    // the axle (Σ m x = −0.21 + 0.40 sin(pitch) kg·m > 0 from pitch 0.55 rad) even standing
    // still is out of reach: the limit is negative.
    let scene = Scene::load(repo_dir().join("params/mobile_manipulator_floating.yaml")).unwrap();
    let mut sys = System::from_scene(&scene).unwrap();
    let em = EnvelopeModel::from_scene(&scene, &sys).unwrap();
    let mut ed = EnvelopeData::new(&em);
    let pitch = sys.model().q_index("arm_shoulder_pitch").unwrap();
    let zero = vec![0.0; sys.model().nv];
    let mut last = f64::INFINITY;
    for p in [0.0, 0.4, 0.8, 1.2, std::f64::consts::FRAC_PI_2] {
        let mut q = scene.q0.clone();
        q[pitch] = p;
        acceleration_envelope(&mut sys, &em, &mut ed, &q, &scene.v0, &zero).unwrap();
        let report = EnvelopeReport::new(sys.model(), &em, &ed.envelope);
        let d = report.forward_deceleration.max.unwrap();
        eprintln!("pitch {p:.3}: braking limit {d:.6} m/s²");
        assert!(d < last, "pitch {p}: {d} after {last}");
        assert_eq!(
            names(&report.forward_deceleration),
            vec![("lift_off".to_string(), "caster_contact".to_string())]
        );
        last = d;
    }
    assert!(last < 0.0, "the arm held forward: {last}");
}

#[test]
fn scene_limits_are_validated_naming_the_constraint_and_field() {
    let path = repo_dir().join("tests/data/cart_tall_mass.yaml");
    let text = std::fs::read_to_string(&path).unwrap();
    let urdf = std::fs::read_to_string(repo_dir().join("urdf/cart_tall_mass.urdf")).unwrap();
    let load = |text: &str| -> Result<Scene, String> {
        let file: SceneFile = serde_yaml::from_str(text).map_err(|e| e.to_string())?;
        let scene = Scene::from_parts(&path, file, &urdf, "cart").map_err(|e| e.to_string())?;
        System::from_scene(&scene).map_err(|e| e.to_string())?;
        Ok(scene)
    };
    let cases = [
        (
            "friction: 0.8",
            "friction: -0.1",
            "left_wheel_contact",
            "friction -0.1",
        ),
        (
            "friction: 0.8",
            "friction: .nan",
            "left_wheel_contact",
            "friction",
        ),
        (
            "rows: [z]",
            "rows: [x, z]",
            "caster_contact",
            "exactly one row",
        ),
        (
            "    unilateral: true",
            "    friction: 0.5",
            "caster_contact",
            "tangential row",
        ),
        (
            "constraints:",
            "passive_joints: [no_such_joint]\nconstraints:",
            "passive_joints",
            "no_such_joint",
        ),
        (
            "constraints:",
            "passive_joints: [root_joint]\nconstraints:",
            "passive_joints",
            "never actuated",
        ),
    ];
    for (from, to, who, what) in cases {
        let bad = text.replacen(from, to, 1);
        assert_ne!(bad, text);
        let e = load(&bad).expect_err(to);
        assert!(e.contains(who) && e.contains(what), "{to}: {e}");
    }
    // A misspelt key is refused by the loader, which names the entry and the field.
    let file = std::env::temp_dir().join(format!("cd_envelope_scene_{}.yaml", std::process::id()));
    let misspelt = text
        .replacen("friction: 0.8", "frictoin: 0.8", 1)
        .replace("../../urdf/", &format!("{}/urdf/", repo_dir().display()));
    std::fs::write(&file, misspelt).unwrap();
    let e = Scene::load(&file).unwrap_err().to_string();
    std::fs::remove_file(&file).ok();
    assert!(
        e.contains("left_wheel_contact") && e.contains("frictoin"),
        "{e}"
    );
    // Defaults: without the new keys the scene loads as before.
    assert!(load(&text).is_ok());
}

#[test]
fn the_floating_mobile_manipulators_envelope_model_holds_the_arm_and_drives_the_wheels() {
    let scene = Scene::load(repo_dir().join("params/mobile_manipulator_floating.yaml")).unwrap();
    let sys = System::from_scene(&scene).unwrap();
    let em = EnvelopeModel::from_scene(&scene, &sys).unwrap();
    let v = |n: &str| sys.model().v_index(n).unwrap();
    let arm = [
        "arm_shoulder_yaw",
        "arm_shoulder_pitch",
        "arm_elbow",
        "arm_wrist",
    ];
    assert_eq!(em.held, arm.map(v).to_vec());
    let actuated: Vec<(&str, f64)> = em
        .actuators
        .iter()
        .map(|a| (a.joint.as_str(), a.effort))
        .collect();
    // URDF efforts: wheels 5 N·m, arm 20 N·m; the base is never actuated.
    assert_eq!(
        actuated,
        [
            ("left_wheel_joint", 5.0),
            ("right_wheel_joint", 5.0),
            ("arm_shoulder_yaw", 20.0),
            ("arm_shoulder_pitch", 20.0),
            ("arm_elbow", 20.0),
            ("arm_wrist", 20.0)
        ]
    );
    // Rows: each wheel t₁, t₂, n; the caster's one unilateral row.
    let contact = |name: &str, normal: usize, tangential: Vec<usize>| Contact {
        name: name.into(),
        normal: Some(normal),
        tangential,
        friction: None,
        sideways_tyre: None,
    };
    assert_eq!(
        em.contacts,
        [
            contact("left_wheel_contact", 2, vec![0, 1]),
            contact("right_wheel_contact", 5, vec![3, 4]),
            contact("caster_contact", 6, vec![])
        ]
    );
    // A passive arm joint is not actuated, and still held.
    let mut passive = scene.clone();
    passive.file.passive_joints = vec!["arm_elbow".into()];
    let em = EnvelopeModel::from_scene(&passive, &sys).unwrap();
    assert!(em.actuators.iter().all(|a| a.joint != "arm_elbow"));
    assert_eq!(em.held.len(), 4);
}

/// Contacts that declare no `friction:`: the envelope as declared (the CLI's) lists their friction
/// unchecked; with an assumed μ (the ROS nodes' `slip.friction_coefficient`) it checks them, and
/// the cart's friction limit is the closed form of that μ. A planar wheel has no normal row: its
/// friction stays unchecked whatever μ is assumed.
#[test]
fn an_assumed_friction_coefficient_checks_the_contacts_that_declare_none() {
    use cart::*;
    let path = repo_dir().join("tests/data/cart_tall_mass.yaml");
    let text = std::fs::read_to_string(&path).unwrap();
    assert_eq!(text.matches("    friction: 0.8\n").count(), 2);
    let file: SceneFile = serde_yaml::from_str(&text.replace("    friction: 0.8\n", "")).unwrap();
    let urdf = repo_dir().join("urdf/cart_tall_mass.urdf");
    let urdf_text = std::fs::read_to_string(&urdf).unwrap();
    let scene = Scene::from_parts(&path, file, &urdf_text, &urdf.display().to_string()).unwrap();
    let mut sys = System::from_scene(&scene).unwrap();
    let declared = EnvelopeModel::from_scene(&scene, &sys).unwrap();
    let friction = |em: &EnvelopeModel| {
        let mut v: Vec<String> = (em.unchecked.iter())
            .filter(|(k, _)| *k == BindingKind::Friction)
            .map(|(_, n)| n.clone())
            .collect();
        v.sort();
        v
    };
    assert_eq!(
        friction(&declared),
        ["left_wheel_contact", "right_wheel_contact"]
    );
    let mu = 0.3;
    let em = declared.assume_friction(mu);
    assert!(friction(&em).is_empty(), "{:?}", em.unchecked);
    let mut ed = EnvelopeData::new(&em);
    let zero = vec![0.0; sys.model().nv];
    acceleration_envelope(&mut sys, &em, &mut ed, &scene.q0, &scene.v0, &zero).unwrap();
    let report = EnvelopeReport::new(sys.model(), &em, &ed.envelope);
    let k = M_Z + 2.0 * I_W / R;
    let expect = mu * G * (M * L_C + M_X) / (M * L_C + mu * k);
    let got = report.forward_acceleration.max.unwrap();
    eprintln!(
        "assumed μ {mu}: a {got} vs {expect} (rel {:.2e})",
        rel(got, expect)
    );
    assert!(rel(got, expect) < TOL, "{got} vs {expect}");
    assert_eq!(
        names(&report.forward_acceleration),
        pair("friction", "left_wheel_contact", "right_wheel_contact")
    );
    // The planar diff drive: no normal rows, so nothing to assume μ against.
    let scene = Scene::load(repo_dir().join("params/diff_drive.yaml")).unwrap();
    let sys = System::from_scene(&scene).unwrap();
    let em = EnvelopeModel::from_scene(&scene, &sys)
        .unwrap()
        .assume_friction(mu);
    assert_eq!(friction(&em), ["left_wheel_contact", "right_wheel_contact"]);
}
