//! Fuzzing every ROS request type without DDS: the pure handlers the ROS plumbing
//! calls — `get_constraint_forces`, `project_velocity`, `filter_command`, `predict`, `rollouts` —
//! and the predictor's inputs (joint states, odometry, twist commands, `/robot_description`
//! text), and a payload (`~/set_payload`'s rebuild), fed hostile floats (NaN, ±∞, ±1e308, 1e-300, −0), wrong-length arrays (0, n−1, n+1, 10 000),
//! unknown / duplicated / empty / unicode joint names, big command lists and odd timestamps.
//!
//! Property per call: no panic; the response is `success = false` with a non-empty message, or
//! every float in it is finite (a message serialised to JSON turns NaN and ±∞ into `null`, so
//! "no `null` anywhere" is "every float finite"); and each call takes less than [`BOUND`] of
//! its thread's CPU time (`rollouts`: [`ROLLOUTS_BOUND`] of the process's).
//!
//! No DDS participant is opened: the nodes are built as `nodes/src/predictor/tests.rs` builds
//! one (`Robot::load` + `NodeLogic::new`). 512 cases per target by default with a fixed seed
//! (`PROPTEST_CASES`, `PROPTEST_RNG_SEED` override; tools/fuzz_long.sh runs more). Each target
//! counts its answered and refused cases and needs both (`Tally`); `FUZZ_WHY=1` prints every
//! refusal's message, to see what the strategies hit.

use crate::fuzz_support;

use constraint_dynamics::model::Payload;
use constraint_dynamics_nodes::forces::{ForcesNode, ForcesParams};
use constraint_dynamics_nodes::msg::builtin_interfaces::Time;
use constraint_dynamics_nodes::msg::constraint_dynamics_msgs::srv::{
    GetConstraintForcesRequest, PredictRequest, ProjectVelocityRequest, RolloutsRequest,
};
use constraint_dynamics_nodes::node::worker::NodeLogic;
use constraint_dynamics_nodes::prediction::{PredictionNode, PredictionParams};
use constraint_dynamics_nodes::predictor::{PredictorInput, PredictorNode, PredictorParams};
use constraint_dynamics_nodes::projection::{ProjectionNode, ProjectionParams};
use constraint_dynamics_nodes::ros::logging::NodeLog;
use fuzz_support::*;
use proptest::prelude::*;

static GET_CONSTRAINT_FORCES: Tally = Tally::new("get_constraint_forces");
static PROJECT_VELOCITY: Tally = Tally::new("project_velocity");
static FILTER_COMMAND: Tally = Tally::new("filter_command (a case: its first command answered)");
static PREDICT: Tally = Tally::new("predict");
static ROLLOUTS: Tally = Tally::new("rollouts");
static PREDICTOR_TICK: Tally = Tally::new("predictor tick (answered: odometry published)");
static ROBOT_DESCRIPTION: Tally = Tally::new("robot_description (answered: robot replaced)");
static SET_PAYLOAD: Tally = Tally::new("set_payload (answered: forces with the payload)");

/// The mobile manipulator's frames a payload may sit on.
const FRAMES: [&str; 5] = ["base_link", "arm_link2", "arm_link4", "tool0", "left_wheel"];

proptest! {
    #![proptest_config(config())]

    #[test]
    fn get_constraint_forces_hostile(
        use_latest_state in any::<bool>(),
        q_names in names(&Q_NAMES),
        q in floats(9),
        v_names in names(&Q_NAMES),
        v in floats(9),
        tau in floats(9),
        js in prop::collection::vec(joint_state(), 0..3),
        now in stamp(),
    ) {
        let _group = crate::common::exclusive_group(module_path!());
        let mut n: ForcesNode = node(ForcesParams::default());
        feed(n.robot_mut(), &js, &[]);
        let req = GetConstraintForcesRequest { use_latest_state, q_names, q, v_names, v, tau };
        let r = timed("get_constraint_forces", || n.get_constraint_forces(&req, now));
        judge("get_constraint_forces", r.success, &r.message, &r).map_err(TestCaseError::fail)?;
        GET_CONSTRAINT_FORCES.count(r.success);
    }

    #[test]
    fn project_velocity_hostile(
        use_latest_state in any::<bool>(),
        q in floats(9),
        v_names in names(&V_NAMES),
        v_des in floats(9),
        use_twist in any::<bool>(),
        base_twist in twist(),
        joint_names in names(&JOINTS),
        joint_velocities in floats(6),
        bound_names in names(&V_NAMES),
        lower in floats(9),
        upper in floats(9),
        accel_limit_dt in hostile(),
        period in hostile(),
        v_current in prop::collection::vec(hostile(), 0..10),
        od in prop::collection::vec(odometry(), 0..2),
        clean in prop::bool::weighted(CLEAN),
    ) {
        let _group = crate::common::exclusive_group(module_path!());
        let mut n: ProjectionNode = node(ProjectionParams::default());
        feed(n.robot_mut(), &[], &od);
        // A clean case: the drawn values made valid (mismatched lengths were most refusals).
        let (use_latest_state, q, v_names, v_des, base_twist, bound_names, lower, upper) = if clean {
            let bounds = |x: &[f64], s: f64| sanitized(x, 9).iter().map(|b| s * (b.abs() + 0.5)).collect();
            (false, sanitized(&q, 9), vec![], sanitized(&v_des, 9), planar(&base_twist),
             V_NAMES.iter().map(|s| s.to_string()).collect(), bounds(&lower, -1.0), bounds(&upper, 1.0))
        } else {
            (use_latest_state, q, v_names, v_des, base_twist, bound_names, lower, upper)
        };
        let (joint_names, joint_velocities, accel_limit_dt) = if clean {
            (JOINTS.iter().map(|s| s.to_string()).collect(), sanitized(&joint_velocities, 6),
             sanitized(&[accel_limit_dt], 1)[0].abs())
        } else {
            (joint_names, joint_velocities, accel_limit_dt)
        };
        // A clean case keeps the period small (a control period) and the start velocity whole.
        let (period, v_current) = if clean {
            (sanitized(&[period], 1)[0].abs() * 0.01, sanitized(&v_current, 9))
        } else {
            (period, v_current)
        };
        let req = ProjectVelocityRequest {
            use_latest_state, q, v_names, v_des, use_twist, base_twist, joint_names,
            joint_velocities, bound_names, lower, upper, accel_limit_dt, period, v_current,
        };
        let r = timed("project_velocity", || n.project_velocity(&req));
        judge("project_velocity", r.success, &r.message, &r).map_err(TestCaseError::fail)?;
        PROJECT_VELOCITY.count(r.success);
    }

    #[test]
    fn filter_command_hostile(
        cmds in prop::collection::vec(twist(), 1..8),
        js in prop::collection::vec(joint_state(), 0..2),
        od in prop::collection::vec(odometry(), 0..2),
    ) {
        let _group = crate::common::exclusive_group(module_path!());
        let mut n: ProjectionNode = node(ProjectionParams::default());
        feed(n.robot_mut(), &js, &od);
        let mut first_answered = None;
        for c in &cmds {
            match timed("filter_command", || n.filter_command(c)) {
                Ok((t, resp)) => {
                    judge("filter_command", resp.success, &resp.message, &resp)
                        .map_err(TestCaseError::fail)?;
                    prop_assert!(all_finite(&t), "filtered twist not finite: {t:?}");
                    first_answered.get_or_insert(resp.success);
                }
                Err(e) => {
                    prop_assert!(!e.to_string().is_empty());
                    first_answered.get_or_insert(false);
                }
            }
        }
        FILTER_COMMAND.count(first_answered == Some(true));
    }

    #[test]
    fn predict_hostile(
        use_latest_state in any::<bool>(),
        q in floats(9),
        v in floats(9),
        commands in prop_oneof![
            8 => prop::collection::vec(twist(), 0..6),
            1 => prop::collection::vec(twist(), 10_000),
        ],
        command_period in prop_oneof![4 => 0.01..0.5f64, 1 => hostile(), 1 => Just(1e-300), 1 => Just(-1.0)],
        horizon in prop_oneof![4 => 0.0..0.6f64, 1 => hostile(), 1 => Just(1e9), 1 => Just(-5.0)],
        with_forces in any::<bool>(),
        with_covariance in any::<bool>(),
        start_covariance in prop_oneof![
            3 => Just(Vec::new()),
            1 => floats(324),
        ],
        js in prop::collection::vec(joint_state(), 0..2),
        od in prop::collection::vec(odometry(), 0..2),
        now in stamp(),
        clean in prop::bool::weighted(CLEAN),
    ) {
        let _group = crate::common::exclusive_group(module_path!());
        let mut n: PredictionNode = node(PredictionParams::default());
        feed(n.robot_mut(), &js, &od);
        let (use_latest_state, q, v, commands, command_period, horizon, start_covariance) = if clean {
            let horizon = if horizon > 0.0 && horizon <= 0.6 { horizon } else { 0.3 };
            (false, sanitized(&q, 9), rolling_velocity(&v), commands.iter().take(6).map(planar).collect(),
             0.1, horizon, vec![])
        } else {
            (use_latest_state, q, v, commands, command_period, horizon, start_covariance)
        };
        let req = PredictRequest {
            use_latest_state, q, v, commands, command_period, horizon, with_forces,
            with_covariance, start_covariance,
        };
        let r = timed("predict", || n.predict(&req, now));
        judge("predict", r.success, &r.message, &r).map_err(TestCaseError::fail)?;
        PREDICT.count(r.success);
    }

    /// `~/rollouts` under limits that keep a case small (8 sequences of at most 0.5 s).
    #[test]
    fn rollouts_hostile(
        use_latest_state in any::<bool>(),
        q in floats(9),
        v in floats(9),
        commands in prop_oneof![
            8 => prop::collection::vec(twist(), 0..24),
            1 => prop::collection::vec(twist(), 10_000),
        ],
        sequence_length in prop_oneof![4 => 1..6u32, 1 => Just(0u32), 1 => any::<u32>()],
        step in prop_oneof![4 => 0.01..0.2f64, 1 => hostile(), 1 => Just(1e-300), 1 => Just(-1.0)],
        with_forces in any::<bool>(),
        js in prop::collection::vec(joint_state(), 0..2),
        od in prop::collection::vec(odometry(), 0..2),
        now in stamp(),
        clean in prop::bool::weighted(CLEAN),
    ) {
        let _group = crate::common::exclusive_group(module_path!());
        // A clean case: 1–8 sequences of 1–5 plausible commands, each held ≤ 0.1 s.
        let (use_latest_state, q, v, commands, sequence_length, step) = if clean {
            let len = if (1..=5).contains(&sequence_length) { sequence_length } else { 2 };
            let n = (commands.len() / len as usize).clamp(1, 8) * len as usize;
            let commands = (0..n)
                .map(|i| commands.get(i).map(planar).unwrap_or_default())
                .collect();
            let step = if step > 0.01 && step <= 0.1 { step } else { 0.05 };
            (false, sanitized(&q, 9), rolling_velocity(&v), commands, len, step)
        } else {
            (use_latest_state, q, v, commands, sequence_length, step)
        };
        let params = PredictionParams {
            max_rollouts: 8,
            max_horizon: 0.5,
            rollout_threads: 2,
            ..Default::default()
        };
        let mut n: PredictionNode = node(params);
        feed(n.robot_mut(), &js, &od);
        let req = RolloutsRequest {
            use_latest_state, q, v, commands, sequence_length, step, with_forces,
        };
        let clock = libc::CLOCK_PROCESS_CPUTIME_ID;
        let r = timed_on(clock, ROLLOUTS_BOUND, "rollouts", || n.rollouts(&req, now));
        judge("rollouts", r.success, &r.message, &r).map_err(TestCaseError::fail)?;
        ROLLOUTS.count(r.success);
        if r.success {
            let len = req.sequence_length as usize;
            prop_assert_eq!(r.poses.len(), req.commands.len());
            prop_assert_eq!(r.twists.len(), req.commands.len());
            prop_assert!(len > 0 && req.commands.len().is_multiple_of(len));
        }
    }

    /// The predictor: commands (plain twists) and state messages in, a tick out.
    #[test]
    fn predictor_inputs_hostile(
        cmds in prop::collection::vec((twist(), stamp()), 0..4),
        js in prop::collection::vec(joint_state(), 0..3),
        od in prop::collection::vec(odometry(), 0..3),
        now in stamp(),
    ) {
        let _group = crate::common::exclusive_group(module_path!());
        let p = PredictorParams { horizon: 0.5, ..Default::default() };
        let mut n: PredictorNode = node(p);
        feed(n.robot_mut(), &js, &od);
        for (c, at) in cmds {
            timed("command", || n.handle(PredictorInput::Command(c), at, &mut |_| {}));
        }
        let mut out = None;
        let r = timed("tick", || n.tick(now, &mut |o| out = Some(o)));
        let published = out.is_some();
        match r {
            Err(e) => prop_assert!(!e.to_string().is_empty()),
            Ok(()) => {
                if let Some(o) = out {
                    prop_assert!(all_finite(&o.odom), "odom: {:?}", o.odom);
                    prop_assert!(all_finite(&o.path), "path not finite");
                    prop_assert!(all_finite(&o.forces), "forces: {:?}", o.forces);
                }
            }
        }
        PREDICTOR_TICK.count(published);
    }

    /// `/robot_description`: truncated or byte-mutated bundled URDF, or random text. The new
    /// robot is refused with a typed error, or is used for one prediction.
    #[test]
    fn robot_description_hostile(
        kind in 0..6u8,
        mass in hostile(),
        cut in 0.0..1.0f64,
        junk in prop::collection::vec(any::<u8>(), 0..64),
        text in any::<String>(),
    ) {
        let _group = crate::common::exclusive_group(module_path!());
        let urdf = match kind {
            0 => URDF[..URDF.floor_char_boundary((cut * URDF.len() as f64) as usize)].to_string(),
            1 => {
                let mut b = URDF.as_bytes().to_vec();
                let at = (cut * b.len() as f64) as usize;
                for (i, x) in junk.iter().enumerate() {
                    if at + i < b.len() {
                        b[at + i] = *x;
                    }
                }
                String::from_utf8_lossy(&b).into_owned()
            }
            2 => text,
            3 => String::from_utf8_lossy(&junk).into_owned(),
            // The bundled URDF whole, its base's mass a drawn number (a plausible one loads).
            _ => URDF.replacen(r#"<mass value="8.0"/>"#, &format!(r#"<mass value="{mass}"/>"#), 1),
        };
        let p = PredictorParams { horizon: 0.3, ..Default::default() };
        let n: PredictorNode = node(p);
        let common = n.params().common.clone();
        let loaded = timed("with_urdf", || n.robot().with_urdf(&urdf, &common));
        ROBOT_DESCRIPTION.count(loaded.is_ok());
        match loaded {
            Err(e) => prop_assert!(!e.to_string().is_empty()),
            Ok(robot) => {
                let params = n.params().clone();
                if let Ok(mut m) = PredictorNode::new(robot, params, NodeLog::new("fuzz")) {
                    let mut out = None;
                    if timed("tick", || m.tick(Time::from_nanos(1), &mut |o| out = Some(o))).is_ok()
                        && let Some(o) = out
                    {
                        prop_assert!(all_finite(&o.odom), "odom: {:?}", o.odom);
                    }
                }
            }
        }
    }

    /// A payload of hostile numbers on a real, unknown or empty frame: the robot carrying it is
    /// refused with a message naming the field, or the forces node rebuilt around it answers
    /// with finite forces.
    #[test]
    fn set_payload_hostile(
        frame in name(&FRAMES),
        mass in prop_oneof![3 => 0.0..50.0f64, 1 => hostile()],
        com in fixed(3),
        inertia in prop_oneof![
            2 => (0.0..1.0f64).prop_map(|a| vec![a, 0.0, 0.0, a, 0.0, a]),
            1 => hostile().prop_map(|a| vec![a, 0.0, 0.0, a, 0.0, a]),
            1 => fixed(6),
        ],
    ) {
        let _group = crate::common::exclusive_group(module_path!());
        let n: ForcesNode = node(ForcesParams::default());
        let common = n.params().common.clone();
        let payload = Payload {
            frame,
            mass,
            com: [com[0], com[1], com[2]],
            inertia: [inertia[0], inertia[1], inertia[2], inertia[3], inertia[4], inertia[5]],
        };
        let loaded = timed("with_payload", || n.robot().with_payload(&payload, &common));
        match loaded {
            Err(e) => {
                let e = e.to_string();
                prop_assert!(e.contains("payload."), "{e}");
                SET_PAYLOAD.count(false);
            }
            Ok(robot) => {
                let mut m = ForcesNode::new(robot, n.params().clone(), NodeLog::new("fuzz"))
                    .map_err(|e| TestCaseError::fail(e.to_string()))?;
                let req = GetConstraintForcesRequest { use_latest_state: true, ..Default::default() };
                let r = timed("get_constraint_forces", || {
                    m.get_constraint_forces(&req, Time::from_nanos(1))
                });
                judge("set_payload", r.success, &r.message, &r).map_err(TestCaseError::fail)?;
                SET_PAYLOAD.count(r.success);
            }
        }
    }
}
