//! Run-time set requests: every value checked when it is set, the whole request judged on the
//! combination it makes, and which parameters a kind has (what it ignores when they are set
//! for every node).

use super::tests::one;
use super::*;
use crate::forces::ForcesParams;
use crate::predictor::PredictorParams;
use crate::projection::ProjectionParams;

fn current<K: KindParams>() -> Parameters {
    let mut p = NodeParams::<K>::default();
    p.common.model.scene_file = "s.yaml".into();
    let mut c = Parameters::default();
    c.values.extend(p.to_ros());
    c
}

fn p(name: &str, value: ParameterValue) -> Parameter {
    Parameter {
        name: name.into(),
        value,
    }
}

fn doubles(x: &[f64]) -> ParameterValue {
    ParameterValue::DoubleArray(x.to_vec())
}

/// The values measured as accepted while `payload.frame` was empty (and then blocking a valid
/// set of `payload.frame`) are refused at once, each naming the parameter and its shape.
#[test]
fn payload_values_are_checked_while_no_frame_is_set() {
    let c = current::<PredictorParams>();
    let cases = [
        (
            "payload.com",
            doubles(&[f64::NAN, 0.0, 0.0]),
            "payload.com = [NaN, 0.0, 0.0]: entry NaN is not finite",
        ),
        (
            "payload.com",
            doubles(&[0.0]),
            "payload.com = [0.0] must be [x, y, z] [m] (3 numbers)",
        ),
        (
            "payload.inertia",
            doubles(&[1.0, 2.0]),
            "payload.inertia = [1.0, 2.0] must be [ixx, ixy, ixz, iyy, iyz, izz] [kg·m²] (6 numbers)",
        ),
        (
            "payload.com",
            doubles(&[f64::INFINITY, 0.0, 0.0]),
            "payload.com = [inf, 0.0, 0.0]: entry inf is not finite",
        ),
        // Not a rigid body's: the principal moments break the triangle inequality.
        (
            "payload.inertia",
            doubles(&[0.3, 0.0, 0.0, 0.1, 0.0, 0.1]),
            "payload.inertia = ",
        ),
        (
            "payload.mass",
            ParameterValue::Double(f64::NAN),
            "payload.mass = NaN kg must be finite",
        ),
    ];
    for (name, value, needle) in cases {
        let e = NodeParams::<PredictorParams>::updated(&c, &one(name, value.clone()), None)
            .unwrap_err()
            .to_string();
        assert!(e.contains(needle), "{name} = {value:?}: {e}");
    }
    // Nothing was stored, so a valid set of another payload parameter goes through.
    let next = NodeParams::<PredictorParams>::updated(
        &c,
        &one("payload.frame", ParameterValue::String("base_link".into())),
        None,
    )
    .unwrap();
    assert_eq!(next.common.payload.frame, "base_link");
}

#[test]
fn a_request_is_judged_on_the_combination_it_makes() {
    let c = current::<ForcesParams>();
    type F = NodeParams<ForcesParams>;
    // A mass needs a frame: alone refused, with the frame in the same request accepted.
    let mass = p("payload.mass", ParameterValue::Double(2.0));
    let e = F::updated(&c, std::slice::from_ref(&mass), None)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("payload.frame is empty but payload.mass = 2 kg"),
        "{e}"
    );
    let frame = p("payload.frame", ParameterValue::String("tool0".into()));
    let com = p("payload.com", doubles(&[0.1, 0.0, 0.2]));
    let both = F::updated(&c, &[mass.clone(), frame.clone(), com], None).unwrap();
    let payload = both.common.payload.payload().unwrap().unwrap();
    assert_eq!(
        (payload.frame.as_str(), payload.mass, payload.com),
        ("tool0", 2.0, [0.1, 0.0, 0.2])
    );
    // One bad member refuses the whole request, naming it.
    let bad = p("payload.inertia", doubles(&[1.0, 2.0]));
    let e = F::updated(&c, &[frame.clone(), mass, bad], None)
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("payload.inertia = [1.0, 2.0]"), "{e}");
    // A parameter fixed while the node runs refuses the request it is in.
    let rate = p("use_sim_time", ParameterValue::Boolean(true));
    let e = F::updated(&c, &[frame, rate], None)
        .unwrap_err()
        .to_string();
    assert!(e.contains("'use_sim_time' cannot change"), "{e}");

    // The projection's limits: names and values change together or not at all.
    let c = current::<ProjectionParams>();
    type P = NodeParams<ProjectionParams>;
    let names = p(
        "acceleration_limits.names",
        ParameterValue::StringArray(vec!["vx".into(), "vy".into(), "wz".into()]),
    );
    let values = p("acceleration_limits.values", doubles(&[1.0, 0.5, 2.0]));
    let e = P::updated(&c, std::slice::from_ref(&names), None)
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("acceleration_limits.values = [1.0, 2.0] must hold one a_max per name"),
        "{e}"
    );
    let next = P::updated(&c, &[names, values], None).unwrap();
    assert_eq!(next.node.acceleration_limits.values, vec![1.0, 0.5, 2.0]);
    let e = P::updated(
        &c,
        &one("acceleration_limits.values", doubles(&[1.0, -2.0])),
        None,
    )
    .unwrap_err()
    .to_string();
    assert!(e.starts_with("acceleration_limits.values (wz) = -2"), "{e}");
}

#[test]
fn a_kind_has_its_declared_names_and_the_keys_of_its_maps() {
    type Pred = NodeParams<PredictorParams>;
    type Forces = NodeParams<ForcesParams>;
    assert!(Pred::has("envelope.velocity_smoother"));
    assert!(!Forces::has("envelope.velocity_smoother"));
    for name in ["rate", "envelope", "markers.footprint"] {
        assert_eq!(Pred::has(name), name != "envelope", "{name}");
    }
    assert!(!Forces::has("rate"));
    for k in [Pred::has, Forces::has] {
        assert!(k("payload.com") && k("slip.friction_coefficient") && k("autostart"));
        assert!(k("state.joint_noise.joints.arm_elbow"));
        assert!(!k("state.joint_noise.joints") && !k("state.joint_noise.joint"));
        assert!(!k("payload") && !k("payload.com.x") && !k("no_such.parameter"));
    }
    // Every name a kind declares, it has.
    let mut p = Pred::default();
    p.common.model.scene_file = "s.yaml".into();
    for (name, _) in p.to_ros() {
        assert!(Pred::has(&name), "{name}");
    }
}

#[test]
fn names_of_model_parts_are_checked_against_the_model() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let scene = constraint_dynamics::Scene::load(root.join("params/suite_mobile_manipulator.yaml"))
        .expect("scene");
    let system = constraint_dynamics::System::from_scene(&scene).expect("system");
    let model = system.model();
    let c = current::<ProjectionParams>();
    type P = NodeParams<ProjectionParams>;
    let set = |changes: &[Parameter]| {
        P::updated(&c, changes, None)
            .unwrap()
            .check_model(model)
            .map_err(|e| e.to_string())
    };
    // The defaults (base aliases vx, wz) fit the planar base.
    set(&[]).unwrap();
    let names = |n: &[&str]| {
        p(
            "acceleration_limits.names",
            ParameterValue::StringArray(n.iter().map(|s| s.to_string()).collect()),
        )
    };
    set(&[names(&["vx", "arm_elbow"])]).unwrap_or_else(|e| panic!("{e}"));
    let e = set(&[names(&["vx", "elbow"])]).unwrap_err();
    assert!(
        e.starts_with(
            "acceleration_limits.names = [\"vx\", \"elbow\"]: unknown velocity coordinate 'elbow'"
        ),
        "{e}"
    );
    let e = set(&[p("payload.frame", ParameterValue::String("gripper".into()))]).unwrap_err();
    assert!(
        e.starts_with("payload.frame = 'gripper' is not a frame of the model (known frames: "),
        "{e}"
    );
    set(&[p("payload.frame", ParameterValue::String("tool0".into()))]).unwrap();
}
