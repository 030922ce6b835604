//! All enabled nodes of the suite in one process (or one of them with `--node KIND`).
//! See docs/nodes.md.

fn main() -> std::process::ExitCode {
    constraint_dynamics_nodes::suite::main(None)
}
