//! `cd_prediction`'s `~/rollouts` runs at the scene's `rollouts:` settings (no ROS: the node's
//! logic called directly): on the differential drive (params/suite_diff_drive.yaml) each
//! rollout equals the core's single prediction of its sequence with the scene's rollout
//! settings, and takes their steps — three per 50 ms command, not the scene's fifty.

use crate::common;

use common::twist;
use constraint_dynamics::actuators::Command;
use constraint_dynamics::predict::{PredictionRequest, Predictor};
use constraint_dynamics_nodes::msg::builtin_interfaces::Time;
use constraint_dynamics_nodes::msg::constraint_dynamics_msgs::srv::RolloutsRequest;
use constraint_dynamics_nodes::node::worker::NodeLogic;
use constraint_dynamics_nodes::params::{CommonParams, NodeParams};
use constraint_dynamics_nodes::prediction::{PredictionNode, PredictionParams};
use constraint_dynamics_nodes::robot::Robot;
use constraint_dynamics_nodes::ros::logging::NodeLog;

const SCENE: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../params/suite_diff_drive.yaml"
);

#[test]
fn rollouts_run_at_the_scenes_rollout_settings() {
    let _group = crate::common::exclusive_group(module_path!());
    let mut common = CommonParams::default();
    common.model.scene_file = SCENE.into();
    let params = NodeParams {
        common,
        node: PredictionParams::default(),
    };
    let robot = Robot::load(&params.common).unwrap();
    let scene = robot.scene().clone();
    assert!(scene.file.rollouts.is_some());
    let mut node = PredictionNode::new(robot, params, NodeLog::new("rollouts")).unwrap();
    let sequences = [
        [(0.4, 0.3), (0.2, -0.5), (-0.3, 0.8)],
        [(0.5, 0.0), (0.5, 1.0), (0.0, -1.0)],
    ];
    let (len, step) = (3, 0.05);
    let req = RolloutsRequest {
        use_latest_state: false,
        q: scene.q0.clone(),
        v: scene.v0.clone(),
        commands: (sequences.iter().flatten())
            .map(|&(v, w)| twist(v, w))
            .collect(),
        sequence_length: len as u32,
        step,
        with_forces: false,
    };
    let r = node.rollouts(&req, Time::default());
    assert!(r.success, "{}", r.message);
    let mut steps = 0;
    for (j, seq) in sequences.iter().enumerate() {
        let cmds: Vec<(f64, Command)> = (seq.iter().enumerate())
            .map(|(k, &(v, w))| {
                let cmd = Command {
                    base_twist: Some([v, w]),
                    ..Default::default()
                };
                (step * k as f64, cmd)
            })
            .collect();
        let mut single = Predictor::from_scene(&scene.rollout_scene())
            .unwrap()
            .with_settings(|s| s.sample_period = step)
            .unwrap();
        let req = PredictionRequest::new(&scene.q0, &scene.v0)
            .commands(&cmds)
            .horizon(len as f64 * step);
        let traj = single.predict(&req).unwrap();
        steps += traj.steps;
        for (k, s) in traj.samples[1..].iter().enumerate() {
            let p = &r.poses[j * len + k].position;
            let gap = (p.x - s.q[0]).hypot(p.y - s.q[1]);
            assert!(gap <= 1e-12, "rollout {j} step {k}: {gap} m");
        }
    }
    // Three ROS2 steps a command, plus one where a saturation exit cuts a step.
    assert!(
        (18..=30).contains(&steps),
        "{steps} integration steps for 2 × 3 commands"
    );
    assert!(
        r.message.contains(&format!("{steps} integration steps")),
        "{}",
        r.message
    );
}
