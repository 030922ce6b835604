//! The `projection` node alone (same as `constraint_dynamics_suite --node projection`). See docs/nodes.md.

use constraint_dynamics_nodes::params::NodeKind;

fn main() -> std::process::ExitCode {
    constraint_dynamics_nodes::suite::main(Some(NodeKind::Projection))
}
