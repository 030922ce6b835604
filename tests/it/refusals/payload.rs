//! A bad `payload:` in a scene, or a bad payload given at run time, is refused with an error
//! that names the field (`payload.frame`, `payload.mass`, `payload.com`, `payload.inertia`).

use crate::common::{assert_has, repo_dir};
use constraint_dynamics::Scene;
use constraint_dynamics::model::Payload;
use constraint_dynamics::scene::SceneFile;

/// The cart's scene with `payload` (YAML lines under `payload:`) added.
fn load(payload: &str) -> Result<Scene, String> {
    let path = repo_dir().join("tests/data/cart_tall_mass.yaml");
    let text = std::fs::read_to_string(&path).unwrap();
    let text = format!("{text}payload:\n{payload}");
    let file: SceneFile = serde_yaml::from_str(&text).map_err(|e| e.to_string())?;
    let urdf = std::fs::read_to_string(repo_dir().join("urdf/cart_tall_mass.urdf")).unwrap();
    Scene::from_parts(&path, file, &urdf, "cart_tall_mass.urdf").map_err(|e| e.to_string())
}

#[test]
fn a_payload_on_an_unknown_frame_names_payload_frame_and_the_known_frames() {
    let e = load("  frame: gripper\n  mass: 2.0\n").unwrap_err();
    assert_has(
        &e,
        &[
            "cart_tall_mass.yaml",
            "payload.frame",
            "unknown frame 'gripper'",
            "tall_mass",
        ],
    );
}

#[test]
fn bad_payload_numbers_are_named() {
    let cases = [
        ("  frame: base_link\n  mass: -1.0\n", "payload.mass"),
        ("  frame: base_link\n  mass: .nan\n", "payload.mass"),
        ("  frame: base_link\n  mass: 1.0e12\n", "payload.mass"),
        (
            "  frame: base_link\n  mass: 1.0\n  com: [0.0, .inf, 0.0]\n",
            "payload.com",
        ),
        // Not positive semidefinite: a principal moment of −0.1 kg·m².
        (
            "  frame: base_link\n  mass: 1.0\n  inertia: [-0.1, 0, 0, 0.1, 0, 0.1]\n",
            "payload.inertia",
        ),
        // Positive definite but no rigid body: 0.3 > 0.1 + 0.1 (triangle inequality).
        (
            "  frame: base_link\n  mass: 1.0\n  inertia: [0.3, 0, 0, 0.1, 0, 0.1]\n",
            "triangle inequality",
        ),
    ];
    for (yaml, field) in cases {
        let e = load(yaml).unwrap_err();
        eprintln!("{e}");
        assert_has(&e, &[field]);
    }
}

#[test]
fn unknown_payload_keys_are_errors_and_mass_zero_is_no_payload() {
    let e = load("  frame: base_link\n  mas: 2.0\n").unwrap_err();
    assert_has(&e, &["unknown field `mas`"]);
    // Mass 0: no payload, whatever the frame says.
    let s = load("  frame: nowhere\n  mass: 0.0\n").unwrap();
    assert_eq!(s.model.total_mass(), s.urdf_model.total_mass());
    // At run time the same checks; an error leaves the scene as it was.
    let e = s
        .with_payload(&Payload::point("base_link", f64::NAN, [0.0; 3]))
        .unwrap_err()
        .to_string();
    assert_has(&e, &["payload.mass"]);
}
