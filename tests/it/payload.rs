//! A payload carried at run time (`payload:` in a scene, `Model::with_payload`) against closed
//! forms — the total mass and centre of mass with a point mass added, the cart's acceleration
//! envelope (docs/projection.md, "The acceleration envelope") with the payload's mass in M,
//! Σ m x and Σ m z — and against the same payload written into the URDF as a fixed link
//! (tests/data/cart_payload_link.urdf): the same M(q), envelope and prediction.

use crate::common;

use common::{cart, repo_dir};
use constraint_dynamics::algorithm::{Data, center_of_mass, crba, forward_kinematics_pos};
use constraint_dynamics::envelope::{
    EnvelopeData, EnvelopeModel, EnvelopeReport, LimitReport, acceleration_envelope,
};
use constraint_dynamics::model::Payload;
use constraint_dynamics::predict::{PredictionRequest, Predictor};
use constraint_dynamics::scene::SceneFile;
use constraint_dynamics::{Model, Scene, System};

/// Relative agreement with the envelope's closed forms: the cone program is solved to 1e-10
/// (gap and feasibility); measured 7.7e-10 at worst (printed).
const TOL: f64 = 1e-8;

/// Where both routes reach the same numbers by the same arithmetic (measured 0): the floor of
/// docs/testing.md.
const EXACT: f64 = 1e-15;

const G: f64 = 9.81;

/// tests/data/cart_tall_mass_payload.yaml's payload: 5 kg at (−0.1, 0, 0.9) m in base_link,
/// which sits 0.1 m above the ground: x = −0.1 m, z = 1.0 m.
mod load {
    pub const M: f64 = 5.0;
    pub const X: f64 = -0.1;
    pub const Z: f64 = 1.0;
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

fn cart_scene_file(name: &str, mu: f64) -> (std::path::PathBuf, SceneFile) {
    let path = repo_dir().join("tests/data").join(name);
    let text = std::fs::read_to_string(&path).unwrap();
    assert_eq!(text.matches("friction: 0.8").count(), 2);
    let text = text.replace("friction: 0.8", &format!("friction: {mu}"));
    (path, serde_yaml::from_str(&text).unwrap())
}

/// A cart scene file with the wheels' μ, on the URDF `urdf` (relative to the repository).
fn scene_on(name: &str, mu: f64, urdf: &str) -> Scene {
    let (path, file) = cart_scene_file(name, mu);
    let text = std::fs::read_to_string(repo_dir().join(urdf)).unwrap();
    Scene::from_parts(&path, file, &text, urdf).unwrap()
}

fn envelope(scene: &Scene) -> EnvelopeReport {
    let mut sys = System::from_scene(scene).unwrap();
    let em = EnvelopeModel::from_scene(scene, &sys).unwrap();
    let mut ed = EnvelopeData::new(&em);
    let zero = vec![0.0; sys.model().nv];
    acceleration_envelope(&mut sys, &em, &mut ed, &scene.q0, &scene.v0, &zero).unwrap();
    EnvelopeReport::new(sys.model(), &em, &ed.envelope)
}

fn binding(limit: &LimitReport) -> Vec<String> {
    let mut v: Vec<String> = limit
        .binding
        .iter()
        .map(|b| format!("{}:{}", b.kind, b.name))
        .collect();
    v.sort();
    v
}

#[test]
fn a_point_payload_adds_its_mass_and_moves_the_centre_of_mass_exactly() {
    let scene = scene_on("cart_tall_mass.yaml", 0.8, "urdf/cart_tall_mass.urdf");
    // 2 kg at (0.3, 0.1, 0.5) m in tall_mass, whose origin is (−0.05, 0, 1.0) m in base_link,
    // 0.1 m above base_footprint (the floating base at the world origin): (0.25, 0.1, 1.6) m.
    let p = Payload::point("tall_mass", 2.0, [0.3, 0.1, 0.5]);
    let loaded = scene.model.with_payload(&p).unwrap();
    let m = cart::M + 2.0;
    assert!(
        rel(loaded.total_mass(), m) < 1e-15,
        "{}",
        loaded.total_mass()
    );
    let expect = nalgebra::Vector3::new(
        (cart::M_X + 2.0 * 0.25) / m,
        (2.0 * 0.1) / m,
        (cart::M_Z + 2.0 * 1.6) / m,
    );
    let mut data = Data::new(&loaded);
    forward_kinematics_pos(&loaded, &mut data, &scene.q0);
    let got = center_of_mass(&loaded, &data);
    eprintln!("centre of mass with a 2 kg point payload: {got:?} vs {expect:?}");
    // Sums of a few products of decimals: a few ulps.
    assert!((got - expect).norm() < 1e-15, "{got:?} vs {expect:?}");
    // The body that carries it is the base (tall_mass is welded to it); the wheels are as
    // they were, and the model given is untouched (the payload makes a new one).
    assert_eq!(loaded.bodies[2].inertia, scene.model.bodies[2].inertia);
    assert!(rel(scene.model.total_mass(), cart::M) < 1e-15);
    // Mass 0 is no payload: the same inertias.
    let none = scene.model.with_payload(&Payload::default()).unwrap();
    for (a, b) in none.bodies.iter().zip(&scene.model.bodies) {
        assert_eq!(a.inertia, b.inertia);
    }
}

#[test]
fn the_payloads_mass_lowers_the_effort_limited_acceleration_as_the_closed_form_says() {
    use cart::*;
    // a = 2 τ_max / (r m_eff), m_eff = M + m_p + 2 I_w / r².
    let m_eff = M + load::M + 2.0 * I_W / (R * R);
    let expect = 2.0 * TAU_MAX / (R * m_eff);
    let scene = Scene::load(repo_dir().join("tests/data/cart_tall_mass_payload.yaml")).unwrap();
    assert!(rel(scene.model.total_mass(), M + load::M) < 1e-15);
    let report = envelope(&scene);
    let got = report.forward_acceleration.max.unwrap();
    eprintln!(
        "effort-limited a with 5 kg: {got} vs {expect} (rel {:.2e}); without: {}",
        rel(got, expect),
        2.0 * TAU_MAX / (R * (M + 2.0 * I_W / (R * R)))
    );
    assert!(rel(got, expect) < TOL, "{got} vs {expect}");
    assert_eq!(
        binding(&report.forward_acceleration),
        ["effort:left_wheel_joint", "effort:right_wheel_joint"]
    );
}

#[test]
fn the_payload_moves_the_friction_and_lift_off_limits_as_the_closed_forms_say() {
    use cart::*;
    // With the payload: M' = M + m_p, Σmx' = Σmx + m_p x_p, Σmz' = Σmz + m_p z_p, K' = Σmz' + 2 I_w/r.
    let m = M + load::M;
    let mx = M_X + load::M * load::X;
    let k = M_Z + load::M * load::Z + 2.0 * I_W / R;
    // Friction (μ = 0.3): a = μ g (M' L_c + Σmx') / (M' L_c + μ K').
    let mu = 0.3;
    let expect = mu * G * (m * L_C + mx) / (m * L_C + mu * k);
    assert!(expect < 2.0 * TAU_MAX / (R * (m + 2.0 * I_W / (R * R))));
    let scene = scene_on(
        "cart_tall_mass_payload.yaml",
        mu,
        "urdf/cart_tall_mass.urdf",
    );
    let report = envelope(&scene);
    let got = report.forward_acceleration.max.unwrap();
    eprintln!(
        "friction-limited a with 5 kg: {got} vs {expect} (rel {:.2e})",
        rel(got, expect)
    );
    assert!(rel(got, expect) < TOL, "{got} vs {expect}");
    assert_eq!(
        binding(&report.forward_acceleration),
        [
            "friction:left_wheel_contact",
            "friction:right_wheel_contact"
        ]
    );
    // Lift-off of the caster when braking: −a = g |Σmx'| / K' (without the payload
    // g |Σmx| / K = 1.988 m/s²; the payload's height lowers it below the effort limit).
    let expect = -G * mx / k;
    assert!(expect < 2.0 * TAU_MAX / (R * (m + 2.0 * I_W / (R * R))));
    let got = report.forward_deceleration.max.unwrap();
    eprintln!(
        "lift-off-limited braking with 5 kg: {got} vs {expect} (rel {:.2e})",
        rel(got, expect)
    );
    assert!(rel(got, expect) < TOL, "{got} vs {expect}");
    assert_eq!(
        binding(&report.forward_deceleration),
        ["lift_off:caster_contact"]
    );
}

/// The payload of tests/data/cart_payload_link.urdf, attached at run time to payload_mount.
fn mount_payload() -> Payload {
    Payload {
        frame: "payload_mount".into(),
        mass: 3.0,
        com: [0.05, -0.02, 0.1],
        inertia: [0.03, 0.004, -0.002, 0.025, 0.003, 0.02],
    }
}

#[test]
fn a_payload_equals_the_same_payload_written_into_the_urdf_as_a_fixed_link() {
    // Two routes to one model: the URDF loader welds the `payload` link to the base body
    // through a turned, offset fixed joint; `with_payload` places the same numbers through
    // payload_mount's placement. The frame is turned (rpy 0.3 −0.2 0.7), so the rotation of
    // the inertia into the body's axes is exercised.
    let mount = scene_on(
        "cart_tall_mass.yaml",
        0.3,
        "tests/data/cart_payload_mount.urdf",
    );
    let link = scene_on(
        "cart_tall_mass.yaml",
        0.3,
        "tests/data/cart_payload_link.urdf",
    );
    let loaded: Model = mount.model.with_payload(&mount_payload()).unwrap();
    assert_eq!(loaded.nbodies(), link.model.nbodies());
    let mut worst: f64 = 0.0;
    for (a, b) in loaded.bodies.iter().zip(&link.model.bodies) {
        worst = worst
            .max((a.inertia.mass - b.inertia.mass).abs())
            .max((a.inertia.com - b.inertia.com).norm())
            .max((a.inertia.inertia_com - b.inertia.inertia_com).norm());
    }
    // M(q) at a generic configuration: the floating base turned and the wheels at odd angles.
    let mut q = mount.q0.clone();
    q[..9].copy_from_slice(&[0.3, -0.2, 0.05, 0.1, -0.2, 0.3, 0.927, 0.7, -1.3]);
    loaded.normalize(&mut q);
    let (mut da, mut db) = (Data::new(&loaded), Data::new(&link.model));
    let ma = crba(&loaded, &mut da, &q).clone();
    let mb = crba(&link.model, &mut db, &q).clone();
    let m_err = (&ma - &mb).abs().max() / mb.abs().max();
    eprintln!("payload vs URDF link: body inertias {worst:.1e}, M(q) {m_err:.1e} (relative)");
    // The loader welds a link with the same placement and parallel-axis sum that
    // `with_payload` uses: measured 0.
    assert!(worst < EXACT, "{worst}");
    assert!(m_err < EXACT, "{m_err}");
    // And the acceleration envelope (μ = 0.3: friction and lift-off bind, both depend on the
    // payload's height and offset).
    let with_payload = mount.with_payload(&mount_payload()).unwrap();
    let (ra, rb) = (envelope(&with_payload), envelope(&link));
    for (what, a, b) in [
        (
            "forward",
            &ra.forward_acceleration,
            &rb.forward_acceleration,
        ),
        (
            "braking",
            &ra.forward_deceleration,
            &rb.forward_deceleration,
        ),
        (
            "yaw left",
            &ra.yaw_acceleration_left,
            &rb.yaw_acceleration_left,
        ),
        (
            "yaw right",
            &ra.yaw_acceleration_right,
            &rb.yaw_acceleration_right,
        ),
    ] {
        let (a, b) = (a.max.unwrap(), b.max.unwrap());
        eprintln!("{what}: {a} vs {b} (rel {:.1e})", rel(a, b));
        // The same cone program from the same numbers: measured 0.
        assert!(rel(a, b) < EXACT, "{what}: {a} vs {b}");
    }
    // And a prediction (the predictor is built from the scene's model): the cart rolling at
    // 0.5 m/s (wheels at v/r = 5 rad/s) for 0.5 s.
    let mut v0 = vec![0.0; 8];
    v0[0] = 0.5;
    (v0[6], v0[7]) = (5.0, 5.0);
    let end = |scene: &Scene| {
        let mut p = Predictor::from_scene(scene).unwrap();
        let t = p
            .predict(&PredictionRequest::new(&scene.q0, &v0).horizon(0.5))
            .unwrap();
        t.samples.last().unwrap().q.clone()
    };
    let (qa, qb) = (end(&with_payload), end(&link));
    eprintln!("prediction end: {qa:?} vs {qb:?}");
    assert!(
        qa.iter()
            .zip(&qb)
            .all(|(a, b)| (a - b).abs() <= EXACT * (1.0 + b.abs()))
    );
    assert!(qa[0] > 0.2, "the cart rolled: x = {}", qa[0]);
    // The scene's payload is the one in use; the URDF's model is kept without it.
    assert_eq!(with_payload.payload, mount_payload());
    assert!(rel(with_payload.model.total_mass(), cart::M + 3.0) < 1e-15);
    assert!(rel(with_payload.urdf_model.total_mass(), cart::M) < 1e-15);
}

#[test]
fn a_payload_on_a_fixed_bases_root_moves_nothing_and_says_so() {
    // params/fourbar.yaml: a fixed base, whose root link `base` is the world's body.
    let scene = Scene::load(repo_dir().join("params/fourbar.yaml")).unwrap();
    let loaded = scene
        .model
        .with_payload(&Payload::point("base", 3.0, [0.1, 0.0, 0.0]))
        .unwrap();
    for (a, b) in loaded.bodies.iter().zip(&scene.model.bodies) {
        assert_eq!(a.inertia, b.inertia);
    }
    let warning = loaded.warnings.last().unwrap();
    assert!(
        warning.contains("'base'") && warning.contains("fixed to the world"),
        "{warning}"
    );
}
