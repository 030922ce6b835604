//! `~/get_constraint_forces` at a state off the constraints, without DDS.

use super::*;
use crate::params::CommonParams;

fn node() -> ForcesNode {
    node_on("params/suite_mobile_manipulator.yaml")
}

/// The forces node on `scene`, a path from the repository's root.
fn node_on(scene: &str) -> ForcesNode {
    let mut common = CommonParams::default();
    common.model.scene_file = format!("{}/../{scene}", env!("CARGO_MANIFEST_DIR"));
    let params = NodeParams::<ForcesParams> {
        common,
        node: ForcesParams::default(),
    };
    let robot = Robot::load(&params.common).unwrap();
    ForcesNode::new(robot, params, NodeLog::new("test")).unwrap()
}

fn request(v: Vec<f64>) -> GetConstraintForcesRequest {
    GetConstraintForcesRequest {
        use_latest_state: false,
        q: vec![0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.5, 1.0, 0.5],
        v,
        ..Default::default()
    }
}

/// The mobile manipulator turning at wz = 0.05 rad/s with both wheels at 4 rad/s (off the
/// rolling rows by ∓0.0085 m/s, where their accelerations disagree): the forces are those of
/// its projection and the reply says from how far, ‖J v‖ = √2 · 0.17 · 0.05 m/s. On the
/// constraints (wheels at (vx ∓ b wz)/r) nothing is said.
#[test]
fn a_state_off_the_constraints_is_projected_and_said() {
    let mut n = node();
    let now = Time::from_nanos(0);
    let off = n.get_constraint_forces(
        &request(vec![0.2, 0.0, 0.05, 4.0, 4.0, 0.0, 0.0, 0.0, 0.0]),
        now,
    );
    assert!(off.success, "{}", off.message);
    let want = format!("|J v| {:.3e}", 2f64.sqrt() * 0.17 * 0.05);
    assert!(
        off.message.contains("state projected onto the constraints") && off.message.contains(&want),
        "{}",
        off.message
    );
    assert!(off.qdd.iter().all(|x| x.is_finite()));
    let (l, r) = ((0.2 - 0.17 * 0.05) / 0.05, (0.2 + 0.17 * 0.05) / 0.05);
    let on = n.get_constraint_forces(
        &request(vec![0.2, 0.0, 0.05, l, r, 0.0, 0.0, 0.0, 0.0]),
        now,
    );
    assert!(on.success && on.message.is_empty(), "{}", on.message);
}

/// The bundled diff drive whose tyres hold it sideways (tests/data/diff_drive_sideways_tyres.yaml)
/// sliding sideways at 5 cm/s on still wheels: each tyre passes μ N v_y/√(v_y² + s₀²) (μ 0.8,
/// N 40 N, s₀ 0.01 m/s) at right angles to its rolling row, and the reply's tangential force is
/// that and the row's λ in quadrature.
#[test]
fn a_sideways_tyres_friction_is_part_of_the_contacts_tangential_force() {
    let mut n = node_on("tests/data/diff_drive_sideways_tyres.yaml");
    let model = n.robot.model();
    let v_y = 0.05;
    let mut v = vec![0.0; model.nv];
    v[model
        .v_names
        .iter()
        .position(|s| s.ends_with("vy_local"))
        .unwrap()] = v_y;
    let req = GetConstraintForcesRequest {
        use_latest_state: false,
        q: vec![0.0; model.nq],
        v,
        ..Default::default()
    };
    let reply = n.get_constraint_forces(&req, Time::from_nanos(0));
    assert!(reply.success, "{}", reply.message);
    let tyre = 0.8 * 40.0 * v_y / (v_y * v_y + 0.01f64.powi(2)).sqrt();
    for c in &reply.forces.constraints {
        let [rolling] = c.multipliers[..] else {
            panic!("{}: rows {:?}", c.name, c.row_names)
        };
        let want = rolling.hypot(tyre);
        println!(
            "{}: λ {rolling:e} N, tangential {} N against {want}",
            c.name, c.tangential_force
        );
        assert!(
            (c.tangential_force - want).abs() < 1e-12,
            "{}",
            c.tangential_force
        );
    }
}
