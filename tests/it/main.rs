//! The core library's integration tests: one target (one link), one module per subject.
//! `cargo test --test it <module>` runs one subject, e.g. `cargo test --test it projection`.

#[path = "common/chain.rs"]
mod chain;
#[path = "common/closed_forms.rs"]
mod closed_forms;
#[path = "common/command_sequences.rs"]
#[allow(dead_code)]
mod command_sequences;
mod common;
// The target's one `#[global_allocator]`: it counts per thread, so the allocation tests run
// beside the others.
#[path = "common/counting_alloc.rs"]
#[allow(dead_code)]
mod counting_alloc;
#[path = "common/planner_settings.rs"]
mod planner_settings;
#[path = "common/properties_support.rs"]
mod properties_support;

mod actuators_anti_windup;
mod actuators_command_lag;
mod algorithm_closed_forms;
mod andrews;
mod bundled_scenes;
mod constraint_conventions;
mod constraint_forces;
mod constraint_kinds;
mod covariance;
mod covariance_bricard;
mod covariance_constrained_noise;
mod covariance_noise;
mod covariance_sensitivity;
mod covariance_worker;
mod derivatives;
mod derivatives_fd;
mod envelope;
mod error_estimate;
mod error_kinds;
mod example_robot_data;
mod invariant_dynamics;
mod linear_constrained_dynamics;
mod linear_dynamics;
mod linear_prediction;
mod linearize;
mod live_prediction;
mod moving_frames;
mod no_alloc;
mod payload;
mod projection;
mod projection_diff_drive;
mod projection_dynamic;
mod projection_dynamic_certificates;
mod projection_kkt;
mod propagation;
mod propagation_a01;
mod propagation_actuator_forces;
mod propagation_closed_forms;
mod propagation_contacts;
mod propagation_formulations;
mod propagation_order;
mod properties;
mod properties_scenes;
mod radau;
mod reference_dynamics;
mod reference_terms;
mod refusals;
mod replay;
mod rollouts;
mod rollouts_planner;
mod sdirk2_steps;
mod seeds;
mod state_map;
mod stiff_extreme;
mod tyres;
mod velocity_constraints;
mod velocity_dependent;
mod velocity_determined;
mod wheel_contacts;
