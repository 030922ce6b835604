//! Where `calibrate`'s parameters go on the bundled scenes (parameters.rs).

use super::*;

/// The bundled scene `params/<name>.yaml`: loaded, as YAML, and its path.
fn bundled(name: &str) -> (crate::Scene, Value, String) {
    let path = format!("{}/params/{name}.yaml", env!("CARGO_MANIFEST_DIR"));
    let yaml = serde_yaml::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    (crate::Scene::load(&path).unwrap(), yaml, path)
}

/// On the soft-floor scene (wheels and balls as `forces.tyres`, no rolling contact): the
/// radius goes to the wheel tyres only, the slip speed to every tyre, the process noise to
/// the wheels' joints; the track offset has nowhere to go.
#[test]
fn tyre_parameters_go_where_the_tyres_are() {
    let (scene, mut yaml, _) = bundled("mobile_manipulator_soft_floor");
    let places = SceneParameters::new(&yaml, &scene.model).unwrap();
    assert_eq!(places.value(&yaml, FitParameter::RollingRadius), 0.04925);
    assert_eq!(places.value(&yaml, FitParameter::TyreSlipSpeed), 0.01);
    assert!(places.unavailable(FitParameter::TrackOffset).is_some());
    assert!(places.unavailable(FitParameter::TyreSlipSpeed).is_none());
    assert_eq!(
        places.wheel_joints(),
        [
            "left_wheel_joint".to_string(),
            "right_wheel_joint".to_string()
        ]
    );
    places.set(&mut yaml, FitParameter::RollingRadius, 0.048);
    places.set(&mut yaml, FitParameter::TyreSlipSpeed, 0.07);
    let radii: Vec<f64> = tyres(&yaml)
        .iter()
        .filter_map(|t| number(t.get("radius")))
        .collect();
    let slips: Vec<f64> = (tyres(&yaml).iter())
        .filter_map(|t| number(t.get("slip_speed_scale")))
        .collect();
    assert_eq!(radii, [0.048, 0.048, 0.025, 0.025]);
    assert_eq!(slips, [0.07; 4]);
}

/// On the suite's scene (two rigid rolling contacts, no tyres), `lateral_creep` c leaves each
/// contact's sideways grip to a tyre at the contact's wheel, axis and radius, carrying half
/// the robot's weight (11.4 kg in the URDF: N = 55.917 N) with s₀ = c μ N; at 0 nothing
/// changes. Once the scene has tyres, it is their `tyre_slip_speed`.
#[test]
fn lateral_creep_adds_sideways_tyres_at_the_contacts() {
    let (scene, yaml, path) = bundled("suite_mobile_manipulator");
    let places = SceneParameters::new(&yaml, &scene.model).unwrap();
    assert!(places.unavailable(FitParameter::LateralCreep).is_none());
    assert_eq!(places.value(&yaml, FitParameter::LateralCreep), 0.0);
    assert!(!places.tyres_carry_wheels());
    let mut rigid = yaml.clone();
    places.set(&mut rigid, FitParameter::LateralCreep, 0.0);
    assert_eq!(rigid, yaml);
    let mut soft = yaml.clone();
    places.set(&mut soft, FitParameter::LateralCreep, 2e-3);
    let n = 11.4 * 9.81 / 2.0;
    for (c, t) in constraints(&soft).iter().zip(tyres(&soft)) {
        assert_eq!(c.get("lateral").and_then(Value::as_str), Some("tyre"));
        assert_eq!(c.get("wheel"), t.get("wheel"));
        assert_eq!(number(t.get("radius")), Some(0.05));
        assert!((number(t.get("normal_force")).unwrap() - n).abs() < 1e-12);
        let s0 = number(t.get("slip_speed_scale")).unwrap();
        assert!((s0 - 2e-3 * LATERAL_FRICTION * n).abs() < 1e-15, "{s0}");
    }
    assert_eq!(tyres(&soft).len(), 2);
    let urdf = concat!(env!("CARGO_MANIFEST_DIR"), "/urdf/mobile_manipulator.urdf");
    let soft_scene = crate::Scene::from_parts(
        std::path::Path::new(&path),
        serde_yaml::from_value(soft.clone()).unwrap(),
        &std::fs::read_to_string(urdf).unwrap(),
        urdf,
    )
    .unwrap();
    crate::predict::Predictor::from_scene(&soft_scene).unwrap();
    let again = SceneParameters::new(&soft, &soft_scene.model).unwrap();
    assert!(again.unavailable(FitParameter::LateralCreep).is_some());
    assert!(again.unavailable(FitParameter::TyreSlipSpeed).is_none());
    assert!(!again.tyres_carry_wheels());
}

/// A command lag needs a diff drive, and a declared lag to start from (the CLI declares one
/// where `--fit` asks for it): each refusal says which is missing.
#[test]
fn a_command_lag_needs_a_diff_drive_and_a_declared_lag() {
    let (scene, yaml, _) = bundled("fourbar");
    let places = SceneParameters::new(&yaml, &scene.model).unwrap();
    let why = places.unavailable(FitParameter::CommandLag).unwrap();
    assert_eq!(why, "the scene has no actuators.diff_drive");
    let (scene, yaml, _) = bundled("suite_mobile_manipulator");
    let places = SceneParameters::new(&yaml, &scene.model).unwrap();
    let why = places.unavailable(FitParameter::CommandLag).unwrap();
    assert_eq!(
        why,
        "the scene declares no actuators.diff_drive.command_lag"
    );
}
