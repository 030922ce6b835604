//! The nodes' integration tests: one target, one module per subject. A test takes its
//! module's group (`common::exclusive_group`), so modules run one at a time as separate
//! binaries did — the load and latency tests see no other suite — while a module's own
//! tests still run side by side.

mod common;
// Counts per thread: the allocation test runs beside the others.
#[path = "../../../tests/it/common/counting_alloc.rs"]
#[allow(dead_code)]
mod counting_alloc;
mod fuzz_support;
mod suite_fixture;

mod bag_reader;
mod fuzz_requests;
mod golden_messages;
mod large_replies;
mod odometry_allocations;
mod prediction_lag;
mod rollout_settings;
mod ros_smoke;
mod suite_absurd_params;
mod suite_bad_input;
mod suite_churn;
mod suite_covariance_rclpy;
mod suite_diff_drive_arc;
mod suite_envelope_rclpy;
mod suite_filter;
mod suite_load;
mod suite_load_pipelined;
mod suite_monitor_log_rclpy;
mod suite_monitor_rclpy;
mod suite_params_rclpy;
mod suite_payload_rclpy;
mod suite_rclpy_peer;
mod suite_services;
mod suite_smoother_missing;
mod suite_stack;
mod suite_stack_rclpy;
mod suite_state_fanout;
mod suite_topics;
