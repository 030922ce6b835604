//! The wheel controllers' state at a prediction's start: a PI's integral is in no message, but
//! its effort is (`JointState.effort`), and so are the joint's velocity and the command it
//! follows; the integral that gives that effort is what the prediction starts from
//! (`Actuators::integrals_from_efforts`, `state.controller_integrals_from_effort`).

use constraint_dynamics::actuators::{Actuators, Command};

use crate::msg::sensor_msgs::JointState;
use crate::robot::state::StateEstimate;

/// The velocity controllers' integrals inferred from the last joint state with efforts.
#[derive(Clone, Debug, Default)]
pub struct ControllerIntegrals {
    /// By v index [rad or m]; empty until a joint state with velocities and efforts came.
    integrals: Vec<f64>,
    /// Scratch: the joint state's velocities and efforts by v index (NaN: not in it).
    v: Vec<f64>,
    effort: Vec<f64>,
}

impl ControllerIntegrals {
    /// Infers the integrals from `js` under `cmd` (the command in force when it came); a
    /// message without velocities or efforts leaves the last ones.
    pub fn joint_state(
        &mut self,
        state: &StateEstimate,
        actuators: &Actuators,
        js: &JointState,
        cmd: &Command,
    ) {
        let n = js.name.len();
        if n == 0 || js.velocity.len() != n || js.effort.len() != n {
            return;
        }
        let nv = state.v.len();
        self.v.clear();
        self.v.resize(nv, f64::NAN);
        self.effort.clear();
        self.effort.resize(nv, f64::NAN);
        for (k, name) in js.name.iter().enumerate() {
            if let Some((_, iv)) = state.joint(name) {
                (self.v[iv], self.effort[iv]) = (js.velocity[k], js.effort[k]);
            }
        }
        self.integrals.resize(nv, 0.0);
        actuators.integrals_from_efforts(cmd, &self.v, &self.effort, &mut self.integrals);
    }

    /// The integrals by v index, empty when none was inferred (every controller at zero).
    pub fn get(&self) -> &[f64] {
        &self.integrals
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use constraint_dynamics::Scene;

    /// The diff drive's wheel PIs (params/suite_diff_drive.yaml) at their targets under
    /// (v, ω): each integral is its effort over ki, by v index, whatever the message's order;
    /// a message without efforts keeps the last.
    #[test]
    fn integrals_are_the_efforts_over_ki_at_the_targets() {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../params/suite_diff_drive.yaml"
        );
        let scene = Scene::load(path).unwrap();
        let spec = &scene.file.actuators;
        let dd = spec.diff_drive.as_ref().unwrap();
        let actuators = Actuators::new(&scene.model, spec).unwrap();
        let state = StateEstimate::new(&scene.model, &scene.q0, &scene.v0);
        let (v, w) = (0.4, 0.5);
        let (r, b) = (dd.wheel_radius, dd.wheel_separation);
        let cmd = Command {
            base_twist: Some([v, w]),
            ..Default::default()
        };
        let js = JointState {
            name: vec!["right_wheel_joint".into(), "left_wheel_joint".into()],
            position: vec![0.0, 0.0],
            velocity: vec![(v + w * b / 2.0) / r, (v - w * b / 2.0) / r],
            effort: vec![0.3, -0.2],
            ..Default::default()
        };
        let mut c = ControllerIntegrals::default();
        assert!(c.get().is_empty());
        c.joint_state(&state, &actuators, &js, &cmd);
        let (_, left) = state.joint("left_wheel_joint").unwrap();
        let (_, right) = state.joint("right_wheel_joint").unwrap();
        let ki = dd.ki;
        assert!((c.get()[right] - 0.3 / ki).abs() < 1e-15 * (0.3 / ki));
        assert!((c.get()[left] + 0.2 / ki).abs() < 1e-15 * (0.2 / ki));
        let before = c.get().to_vec();
        let no_effort = JointState {
            effort: vec![],
            ..js
        };
        c.joint_state(&state, &actuators, &no_effort, &cmd);
        assert_eq!(c.get(), &before[..]);
    }
}
