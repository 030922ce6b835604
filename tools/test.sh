#!/usr/bin/env bash
# Run every test of the project: the core library, the CLI, the ROS 2 nodes, and the interop
# suite against real ROS 2 peers (rclpy, Cyclone DDS).
#
# The network rule: DDS multicasts discovery on every interface, so every test process runs
# inside a private network namespace that has only loopback (tools/ros2/netns_run.sh). Downloads
# (crates, the pinned Python peer venv) happen first, outside it; nothing in the namespace can
# reach the network.
set -euo pipefail
cd "$(dirname "$0")/.."

cargo fetch --locked
bash tools/ros2/setup_peer_venv.sh
cargo build --workspace --all-targets --locked --offline
tools/ros2/netns_run.sh env CD_REQUIRE_PEER=1 cargo test --workspace --locked --offline
