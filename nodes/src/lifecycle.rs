//! The managed-node state machine of ROS 2 (rcl_lifecycle's default machine, design article
//! "Managed nodes"), as plain data: no ROS handles, unit-tested here.
//!
//! ```text
//!              configure            activate
//! unconfigured ─────────► inactive ─────────► active
//!      ▲  ◄─────────────    │  ◄──────────────   │
//!      │      cleanup       │     deactivate     │
//!      └──── shutdown ──────┴──── shutdown ──────┴──► finalized
//! ```
//!
//! A transition runs through its transition state (`configuring`, …): the node's callback
//! decides the outcome — success reaches the goal, failure returns to the start state (as
//! rclcpp does on `FAILURE`). Each step is a [`TransitionEvent`] with the ids and labels of
//! `lifecycle_msgs` (what rclcpp publishes on `~/transition_event`).

use crate::msg::lifecycle_msgs::{self as lm, TransitionDescription, TransitionEvent};

/// A state of the machine (primary 1–4, transition 10–15; ids of `lifecycle_msgs/State`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum State {
    /// Created, nothing loaded.
    Unconfigured = 1,
    /// Configured (scene loaded, inputs followed), not publishing or serving.
    Inactive = 2,
    /// Publishing and serving.
    Active = 3,
    /// Shut down; only destruction is left.
    Finalized = 4,
    /// Running `on_configure`.
    Configuring = 10,
    /// Running `on_cleanup`.
    CleaningUp = 11,
    /// Running `on_shutdown`.
    ShuttingDown = 12,
    /// Running `on_activate`.
    Activating = 13,
    /// Running `on_deactivate`.
    Deactivating = 14,
    /// Running `on_error`.
    ErrorProcessing = 15,
}

impl State {
    /// Every state rcl_lifecycle's default machine has, in id order.
    pub const ALL: [State; 10] = [
        State::Unconfigured,
        State::Inactive,
        State::Active,
        State::Finalized,
        State::Configuring,
        State::CleaningUp,
        State::ShuttingDown,
        State::Activating,
        State::Deactivating,
        State::ErrorProcessing,
    ];

    /// The `lifecycle_msgs/State` id.
    pub fn id(self) -> u8 {
        self as u8
    }

    /// rcl_lifecycle's label.
    pub fn label(self) -> &'static str {
        match self {
            State::Unconfigured => "unconfigured",
            State::Inactive => "inactive",
            State::Active => "active",
            State::Finalized => "finalized",
            State::Configuring => "configuring",
            State::CleaningUp => "cleaningup",
            State::ShuttingDown => "shuttingdown",
            State::Activating => "activating",
            State::Deactivating => "deactivating",
            State::ErrorProcessing => "errorprocessing",
        }
    }

    /// As a message.
    pub fn msg(self) -> lm::State {
        lm::State {
            id: self.id(),
            label: self.label().into(),
        }
    }
}

/// A transition a manager can ask for (ids of `lifecycle_msgs/Transition`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Transition {
    /// unconfigured → inactive.
    Configure = 1,
    /// inactive → unconfigured.
    Cleanup = 2,
    /// inactive → active.
    Activate = 3,
    /// active → inactive.
    Deactivate = 4,
    /// unconfigured → finalized.
    UnconfiguredShutdown = 5,
    /// inactive → finalized.
    InactiveShutdown = 6,
    /// active → finalized.
    ActiveShutdown = 7,
}

/// What a node does in a transition (its `on_configure`, `on_activate`, … callback).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Callback {
    /// Load the scene, start the worker, follow the state inputs.
    Configure,
    /// Stop the worker and the inputs.
    Cleanup,
    /// Create the publishers, servers and the command input; start predicting.
    Activate,
    /// Remove them; stop predicting.
    Deactivate,
    /// Release everything.
    Shutdown,
}

impl Transition {
    /// Every transition, in id order.
    pub const ALL: [Transition; 7] = [
        Transition::Configure,
        Transition::Cleanup,
        Transition::Activate,
        Transition::Deactivate,
        Transition::UnconfiguredShutdown,
        Transition::InactiveShutdown,
        Transition::ActiveShutdown,
    ];

    /// The `lifecycle_msgs/Transition` id.
    pub fn id(self) -> u8 {
        self as u8
    }

    /// rcl_lifecycle's label (the three shutdowns share `shutdown`).
    pub fn label(self) -> &'static str {
        match self {
            Transition::Configure => "configure",
            Transition::Cleanup => "cleanup",
            Transition::Activate => "activate",
            Transition::Deactivate => "deactivate",
            _ => "shutdown",
        }
    }

    /// (start, transition state, goal on success, callback).
    fn path(self) -> (State, State, State, Callback) {
        use State::*;
        match self {
            Transition::Configure => (Unconfigured, Configuring, Inactive, Callback::Configure),
            Transition::Cleanup => (Inactive, CleaningUp, Unconfigured, Callback::Cleanup),
            Transition::Activate => (Inactive, Activating, Active, Callback::Activate),
            Transition::Deactivate => (Active, Deactivating, Inactive, Callback::Deactivate),
            Transition::UnconfiguredShutdown => {
                (Unconfigured, ShuttingDown, Finalized, Callback::Shutdown)
            }
            Transition::InactiveShutdown => (Inactive, ShuttingDown, Finalized, Callback::Shutdown),
            Transition::ActiveShutdown => (Active, ShuttingDown, Finalized, Callback::Shutdown),
        }
    }

    /// The state the transition starts from.
    pub fn start(self) -> State {
        self.path().0
    }

    /// The callback that decides it.
    pub fn callback(self) -> Callback {
        self.path().3
    }

    /// Id of the callback-result transition (`TRANSITION_ON_<X>_SUCCESS` = 10, 20, … and
    /// `_FAILURE` one more).
    fn result_id(self, success: bool) -> u8 {
        let base = match self.callback() {
            Callback::Configure => 10,
            Callback::Cleanup => 20,
            Callback::Activate => 30,
            Callback::Deactivate => 40,
            Callback::Shutdown => 50,
        };
        if success { base } else { base + 1 }
    }

    /// As a message.
    pub fn msg(self) -> lm::Transition {
        lm::Transition {
            id: self.id(),
            label: self.label().into(),
        }
    }
}

/// A refused `change_state` request.
#[derive(Debug, PartialEq, Eq, thiserror::Error)]
pub enum LifecycleError {
    /// Neither a known id nor a known label.
    #[error("unknown transition id {id} label {label:?}")]
    Unknown {
        /// The id asked for.
        id: u8,
        /// The label asked for.
        label: String,
    },
    /// Known, but not from the current state.
    #[error("transition '{transition}' is not available in state '{state}'")]
    NotAvailable {
        /// The transition's label.
        transition: &'static str,
        /// The current state's label.
        state: &'static str,
    },
    /// Activation asked of a node that holds no configuration.
    #[error("not configured")]
    NotConfigured,
}

/// The machine: the current primary state.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Lifecycle {
    state: State,
}

impl Default for Lifecycle {
    fn default() -> Self {
        Lifecycle {
            state: State::Unconfigured,
        }
    }
}

/// One run of a transition, between [`Lifecycle::begin`] and [`Lifecycle::finish`].
#[derive(Debug, PartialEq, Eq)]
pub struct Pending {
    transition: Transition,
}

impl Pending {
    /// The transition being run.
    pub fn transition(&self) -> Transition {
        self.transition
    }
}

impl Lifecycle {
    /// The current state.
    pub fn state(&self) -> State {
        self.state
    }

    /// The transition a request names: by id, or by label when the id is 0 (`create`, which
    /// no request can ask for) — as rclcpp's `change_state` service does. A `shutdown`
    /// label picks the shutdown of the current state.
    pub fn resolve(&self, req: &lm::Transition) -> Result<Transition, LifecycleError> {
        let unknown = || LifecycleError::Unknown {
            id: req.id,
            label: req.label.clone(),
        };
        if req.id != 0 {
            return Transition::ALL
                .into_iter()
                .find(|t| t.id() == req.id)
                .ok_or_else(unknown);
        }
        let mut named = Transition::ALL
            .into_iter()
            .filter(|t| t.label() == req.label);
        let first = named.next().ok_or_else(unknown)?;
        Ok(std::iter::once(first)
            .chain(named)
            .find(|t| t.start() == self.state)
            .unwrap_or(first))
    }

    /// The transitions available in the current state (what `~/get_available_transitions`
    /// lists: goal = the transition state, as rcl_lifecycle reports it).
    pub fn available(&self) -> Vec<Transition> {
        Transition::ALL
            .into_iter()
            .filter(|t| t.start() == self.state)
            .collect()
    }

    /// `available` as messages.
    pub fn available_msgs(&self) -> Vec<TransitionDescription> {
        self.available()
            .into_iter()
            .map(|t| TransitionDescription {
                transition: t.msg(),
                start_state: t.start().msg(),
                goal_state: t.path().1.msg(),
            })
            .collect()
    }

    /// Starts `t`: the machine enters its transition state. The event is the first of the
    /// two a transition publishes.
    pub fn begin(
        &mut self,
        t: Transition,
        timestamp: u64,
    ) -> Result<(Pending, TransitionEvent), LifecycleError> {
        if t.start() != self.state {
            return Err(LifecycleError::NotAvailable {
                transition: t.label(),
                state: self.state.label(),
            });
        }
        let (start, middle, _, _) = t.path();
        self.state = middle;
        let event = TransitionEvent {
            timestamp,
            transition: t.msg(),
            start_state: start.msg(),
            goal_state: middle.msg(),
        };
        Ok((Pending { transition: t }, event))
    }

    /// Ends a transition with its callback's outcome: success reaches the goal, failure
    /// returns to the start state. The event is the second one.
    pub fn finish(&mut self, p: Pending, success: bool, timestamp: u64) -> TransitionEvent {
        let t = p.transition;
        let (start, middle, goal, _) = t.path();
        self.state = if success { goal } else { start };
        let id = t.result_id(success);
        let label = match success {
            true => "transition_success",
            false => "transition_failure",
        };
        TransitionEvent {
            timestamp,
            transition: lm::Transition {
                id,
                label: label.into(),
            },
            start_state: middle.msg(),
            goal_state: self.state.msg(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn req(id: u8, label: &str) -> lm::Transition {
        lm::Transition {
            id,
            label: label.into(),
        }
    }

    /// Runs `t` to the end with `success`; returns both events.
    fn run(m: &mut Lifecycle, t: Transition, success: bool) -> [TransitionEvent; 2] {
        let (p, a) = m.begin(t, 1).unwrap();
        assert_eq!(
            m.state(),
            t.path().1,
            "in the transition state while it runs"
        );
        let b = m.finish(p, success, 2);
        [a, b]
    }

    #[test]
    fn ids_and_labels_are_those_of_lifecycle_msgs() {
        // lifecycle_msgs/msg/State.msg and Transition.msg (Jazzy/Kilted).
        let states: Vec<(u8, &str)> = State::ALL.iter().map(|s| (s.id(), s.label())).collect();
        assert_eq!(
            states,
            [
                (1, "unconfigured"),
                (2, "inactive"),
                (3, "active"),
                (4, "finalized"),
                (10, "configuring"),
                (11, "cleaningup"),
                (12, "shuttingdown"),
                (13, "activating"),
                (14, "deactivating"),
                (15, "errorprocessing"),
            ]
        );
        let ids: Vec<u8> = Transition::ALL.iter().map(|t| t.id()).collect();
        assert_eq!(ids, [1, 2, 3, 4, 5, 6, 7]);
        assert_eq!(Transition::Configure.result_id(true), 10);
        assert_eq!(Transition::Configure.result_id(false), 11);
        assert_eq!(Transition::Cleanup.result_id(true), 20);
        assert_eq!(Transition::Activate.result_id(true), 30);
        assert_eq!(Transition::Deactivate.result_id(false), 41);
        assert_eq!(Transition::ActiveShutdown.result_id(true), 50);
    }

    #[test]
    fn full_cycle_as_a_lifecycle_manager_drives_it() {
        let mut m = Lifecycle::default();
        assert_eq!(m.state(), State::Unconfigured);
        let ids = |m: &Lifecycle| m.available().iter().map(|t| t.id()).collect::<Vec<_>>();
        assert_eq!(ids(&m), [1, 5]);
        let [a, b] = run(&mut m, Transition::Configure, true);
        assert_eq!(
            (a.start_state.id, a.goal_state.id, a.transition.id),
            (1, 10, 1)
        );
        assert_eq!(
            (b.start_state.id, b.goal_state.id, b.transition.id),
            (10, 2, 10)
        );
        assert_eq!(m.state(), State::Inactive);
        assert_eq!(ids(&m), [2, 3, 6]);
        run(&mut m, Transition::Activate, true);
        assert_eq!(m.state(), State::Active);
        assert_eq!(ids(&m), [4, 7]);
        let goals: Vec<u8> = m.available_msgs().iter().map(|d| d.goal_state.id).collect();
        assert_eq!(
            goals,
            [14, 12],
            "goal = the transition state, as rcl reports it"
        );
        run(&mut m, Transition::Deactivate, true);
        assert_eq!(m.state(), State::Inactive);
        run(&mut m, Transition::Cleanup, true);
        assert_eq!(m.state(), State::Unconfigured);
        let [_, b] = run(&mut m, Transition::UnconfiguredShutdown, true);
        assert_eq!((b.goal_state.id, b.transition.id), (4, 50));
        assert_eq!(m.state(), State::Finalized);
        assert!(m.available().is_empty());
    }

    #[test]
    fn a_failed_callback_returns_to_the_start_state() {
        let mut m = Lifecycle::default();
        let [_, b] = run(&mut m, Transition::Configure, false);
        assert_eq!(m.state(), State::Unconfigured);
        assert_eq!((b.transition.id, b.goal_state.id), (11, 1));
        run(&mut m, Transition::Configure, true);
        let [_, b] = run(&mut m, Transition::Activate, false);
        assert_eq!(m.state(), State::Inactive);
        assert_eq!(b.transition.id, 31);
    }

    #[test]
    fn refused_requests_leave_the_state_alone() {
        let mut m = Lifecycle::default();
        let err = m.begin(Transition::Activate, 0).unwrap_err();
        assert_eq!(
            err.to_string(),
            "transition 'activate' is not available in state 'unconfigured'"
        );
        assert_eq!(m.state(), State::Unconfigured);
        assert!(matches!(
            m.resolve(&req(9, "")),
            Err(LifecycleError::Unknown { id: 9, .. })
        ));
        assert!(m.resolve(&req(0, "fly")).is_err());
        assert!(m.resolve(&req(0, "")).is_err());
    }

    #[test]
    fn requests_by_label_pick_the_transition_of_the_current_state() {
        let mut m = Lifecycle::default();
        assert_eq!(m.resolve(&req(0, "configure")), Ok(Transition::Configure));
        assert_eq!(
            m.resolve(&req(0, "shutdown")),
            Ok(Transition::UnconfiguredShutdown)
        );
        run(&mut m, Transition::Configure, true);
        run(&mut m, Transition::Activate, true);
        assert_eq!(
            m.resolve(&req(0, "shutdown")),
            Ok(Transition::ActiveShutdown)
        );
        // An id wins over the label.
        assert_eq!(m.resolve(&req(4, "configure")), Ok(Transition::Deactivate));
    }
}
