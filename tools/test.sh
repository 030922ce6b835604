#!/usr/bin/env bash
# Run every test of the project: the core library, the CLI, the ROS 2 nodes, and the interop
# suite against real ROS 2 peers (rclpy with rmw_fastrtps_cpp, Cyclone DDS) of two
# distributions: Kilted (.venv-ros2, every test) and Jazzy, the LTS most robots run
# (.venv-ros2-jazzy: the tests with an rclpy or Cyclone peer, and the interop suite); then the
# node package as colcon installs it (tools/ros2/check_colcon_install.sh).
#
# The network rule: DDS multicasts discovery on every interface, so every test process runs
# inside a private network namespace that has only loopback (tools/ros2/netns_run.sh). Downloads
# (crates, the pinned Python venvs) happen first, outside it; nothing in the namespace can
# reach the network.
set -euo pipefail
cd "$(dirname "$0")/.."

# Wall time per phase: a `phase NAME: N s` line as each ends, and all of them again at the end.
phases=()
phase_start=$SECONDS
phase() {
    phases+=("phase $1: $((SECONDS - phase_start)) s")
    echo "${phases[-1]}"
    phase_start=$SECONDS
}

cargo fetch --locked
phase fetch
# The pinned venvs download (network) while cargo builds (CPU); their log is shown on failure.
{
    venvs_start=$SECONDS
    bash tools/ros2/setup_peer_venv.sh
    bash tools/ros2/setup_peer_venv.sh --distro jazzy
    bash tools/robots/setup_venv.sh     # Pinocchio + example-robot-data (tests/it/example_robot_data.rs)
    bash tools/ros2/check_colcon_install.sh setup   # colcon + colcon-ros-cargo + cargo-ament-build
    echo "phase venvs (beside the build): $((SECONDS - venvs_start)) s"
} > /tmp/cd_venvs.log 2>&1 &
venvs=$!
# What the tests run: the libraries, the binaries and every test target (the criterion benches
# are left out: clippy --all-targets compiles them, and no test runs them). The colcon build
# (tools/ros2/check_colcon_install.sh) asks for the same targets, so it finds them built.
cargo build --workspace --bins --tests --locked --offline
phase build
wait "$venvs" || { cat /tmp/cd_venvs.log >&2; echo "the venv setup failed" >&2; exit 1; }
cat /tmp/cd_venvs.log
phases+=("$(tail -1 /tmp/cd_venvs.log)")
phase "venvs (after the build)"

# Rust tests, then the rclpy/Cyclone interop suite, in one private namespace each. The DDS tests
# are #[ignore]d in a plain `cargo test` (they need root and the peer venv, both set up here):
# --include-ignored runs them, and a missing prerequisite fails them. Every nodes/tests/it module
# runs here, the robustness ones included: suite_load (~85 s; CD_LOAD_SECONDS, default
# 60), suite_churn (~75 s; CD_CHURN_PARTICIPANTS, default 1000), suite_absurd_params (~15 s).
set +e
tools/ros2/netns_run.sh cargo test --workspace --locked --offline -- --include-ignored 2>&1 | tee /tmp/cd_cargo_test.log
cargo_status=${PIPESTATUS[0]}
phase "cargo test (Kilted peers)"
tools/ros2/netns_run.sh .venv-ros2/bin/python tools/ros2/interop/interop.py 2>&1 | grep -v '^\[\(ERROR\|WARN\)\]' | tee /tmp/cd_interop.log
interop_status=${PIPESTATUS[0]}
phase "interop (Kilted)"
# The same peer tests against Jazzy's rclpy (rmw_fastrtps_cpp 8.4 / Fast DDS 2.14). --workspace,
# not -p: the features cargo unifies are then the first run's, so nothing is rebuilt (the other
# crates' `it` targets match no filter and run nothing).
CD_ROS2_VENV="$PWD/.venv-ros2-jazzy" tools/ros2/netns_run.sh cargo test --workspace \
    --locked --offline --test it -- --include-ignored suite_rclpy_peer:: suite_stack_rclpy:: \
    suite_covariance_rclpy:: suite_payload_rclpy:: suite_params_rclpy:: suite_monitor_rclpy:: \
    suite_monitor_log_rclpy:: suite_envelope_rclpy:: ros_smoke:: 2>&1 | tee /tmp/cd_cargo_test_jazzy.log
jazzy_status=${PIPESTATUS[0]}
phase "cargo test (Jazzy peers)"
tools/ros2/netns_run.sh .venv-ros2-jazzy/bin/python tools/ros2/interop/interop.py 2>&1 | grep -v '^\[\(ERROR\|WARN\)\]' | tee /tmp/cd_interop_jazzy.log
interop_jazzy_status=${PIPESTATUS[0]}
phase "interop (Jazzy)"
# The node package as colcon installs it (nodes/package.xml), and the installed suite started.
{ bash tools/ros2/check_colcon_install.sh build && tools/ros2/netns_run.sh \
    tools/ros2/check_colcon_install.sh run; } 2>&1 | tee /tmp/cd_colcon.log
colcon_status=${PIPESTATUS[0]}
phase colcon
set -e

# One closing line over everything: cargo's test counts plus the interop checks. With
# --include-ignored cargo ignores nothing: a non-zero count means a test did not run, a failure.
read -r rust_passed rust_failed rust_ignored < <(grep -hE '^test result:' /tmp/cd_cargo_test.log \
    /tmp/cd_cargo_test_jazzy.log | awk '{p += $4; f += $6; i += $8} END {print p + 0, f + 0, i + 0}')
py_passed=0
py_failed=0
for log in /tmp/cd_interop.log /tmp/cd_interop_jazzy.log; do
    p=
    f=
    read -r p f < <(grep -E '^interop: [0-9]+ passed' "$log" | awk '{print $2, $4}' | tail -1) || true
    py_passed=$((py_passed + ${p:-0}))
    py_failed=$((py_failed + ${f:-1})) # no closing line: the interop run failed
done
read -r colcon_passed colcon_failed < <(grep -E '^colcon: [0-9]+ passed' /tmp/cd_colcon.log \
    | awk '{p += $2; f += $4} END {print p + 0, f + 0}')
[[ $colcon_status -eq 0 ]] || colcon_failed=$((colcon_failed > 0 ? colcon_failed : 1))
py_passed=$((py_passed + colcon_passed))
py_failed=$((py_failed + colcon_failed))
printf '%s\n' "${phases[@]}" "phase total: $SECONDS s"
echo "cargo ignored $rust_ignored tests (0 expected: every test runs with --include-ignored)"
echo "all: $((rust_passed + py_passed)) passed, $((rust_failed + py_failed)) failed, $rust_ignored skipped"
if [[ $cargo_status -ne 0 || $interop_status -ne 0 || $jazzy_status -ne 0 \
    || $interop_jazzy_status -ne 0 || $colcon_status -ne 0 || $rust_ignored -ne 0 ]]; then
    exit 1
fi
