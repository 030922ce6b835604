#!/usr/bin/env bash
# Run every test of the project: the core library, the CLI, the ROS 2 nodes, and the interop
# suite against real ROS 2 peers (rclpy with rmw_fastrtps_cpp, Cyclone DDS).
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

# Rust tests, then the rclpy/Cyclone interop suite, in one private namespace each.
set +e
tools/ros2/netns_run.sh env CD_REQUIRE_PEER=1 cargo test --workspace --locked --offline 2>&1 | tee /tmp/cd_cargo_test.log
cargo_status=${PIPESTATUS[0]}
tools/ros2/netns_run.sh .venv-ros2/bin/python tools/ros2/interop/interop.py 2>&1 | grep -v '^\[\(ERROR\|WARN\)\]' | tee /tmp/cd_interop.log
interop_status=${PIPESTATUS[0]}
set -e

# One closing line over everything: cargo's test counts plus the interop checks.
read -r rust_passed rust_failed < <(grep -E '^test result:' /tmp/cd_cargo_test.log \
    | awk '{p += $4; f += $6} END {print p + 0, f + 0}')
read -r py_passed py_failed < <(grep -E '^interop: [0-9]+ passed' /tmp/cd_interop.log \
    | awk '{print $2, $4}' | tail -1)
py_passed=${py_passed:-0}
py_failed=${py_failed:-1}
echo "all: $((rust_passed + py_passed)) passed, $((rust_failed + py_failed)) failed"
if [[ $cargo_status -ne 0 || $interop_status -ne 0 ]]; then
    exit 1
fi
