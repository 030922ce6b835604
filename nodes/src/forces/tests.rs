//! `~/get_constraint_forces` at a state off the constraints, without DDS.

use super::*;
use crate::params::CommonParams;

fn node() -> ForcesNode {
    let mut common = CommonParams::default();
    common.model.scene_file = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../params/suite_mobile_manipulator.yaml"
    )
    .into();
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
