#!/usr/bin/env bash
# Check that colcon builds and installs the node package as a ROS 2 user's workspace would:
# colcon-ros-cargo sees nodes/package.xml (build type ament_cargo) and runs cargo-ament-build,
# which installs the binaries to lib/constraint_dynamics_nodes/ and, from
# [package.metadata.ros] in nodes/Cargo.toml, the launch file, the parameter files and the
# bundled robots to share/constraint_dynamics_nodes/. Then the installed suite is started from
# the installed parameter file (inside the private network namespace: it opens a DDS
# participant) and must load its scene from the share directory and keep running.
#
#   tools/ros2/check_colcon_install.sh setup   # pinned colcon venv from PyPI (needs the network)
#   tools/ros2/check_colcon_install.sh build   # colcon build + install-tree checks (no DDS)
#   tools/ros2/netns_run.sh tools/ros2/check_colcon_install.sh run   # the installed suite
#
# Prints `colcon: N passed, M failed` per stage and exits non-zero on any failure.
# launch_ros is not published on PyPI, so `ros2 launch` itself is not run here: the launch file
# is compiled and every path it resolves through ament_index is checked in the install tree.
set -euo pipefail

HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
REPO=$(cd "$HERE/../.." && pwd)
VENV=${CD_COLCON_VENV:-$REPO/.venv-colcon}
PEER_VENV=${CD_ROS2_VENV:-$REPO/.venv-ros2}   # for ament_index_python
PYTHON=${PYTHON:-python3}
PINS=(colcon-core==0.21.3 colcon-ros==0.5.0 colcon-cargo==0.2.0 colcon-ros-cargo==0.2.0
    cargo-ament-build==0.1.11)
WS=$REPO/target/colcon
PKG=constraint_dynamics_nodes
INSTALL=$WS/install/$PKG
SHARE=$INSTALL/share/$PKG

passed=0
failed=0
check() { # check NAME COMMAND...: one counted check
    local name=$1
    shift
    if "$@"; then
        passed=$((passed + 1))
    else
        failed=$((failed + 1))
        echo "colcon: FAILED: $name" >&2
    fi
}
finish() {
    echo "colcon: $passed passed, $failed failed"
    [[ $failed -eq 0 ]]
}

case "${1:-}" in
setup)
    STAMP="$VENV/.cd_colcon_stamp"
    WANT=$(printf '%s\n' "stamp-v1" "${PINS[@]}")
    if [[ ! (-f "$STAMP" && "$(cat "$STAMP")" == "$WANT" && -x "$VENV/bin/colcon") ]]; then
        rm -f "$STAMP"
        [[ -x "$VENV/bin/python" ]] || "$PYTHON" -m venv "$VENV"
        "$VENV/bin/python" -m pip install --disable-pip-version-check -q "${PINS[@]}"
        printf '%s\n' "$WANT" > "$STAMP"
    fi
    # colcon crawls for package.xml files: the venvs (gitignored) hold the ROS wheels' own.
    for venv in "$REPO"/.venv*/; do touch "$venv/COLCON_IGNORE"; done
    echo "colcon: venv ready: $VENV"
    ;;
build)
    rm -rf "$WS/install" "$WS/log"
    mkdir -p "$WS/build"
    # The package's cargo target directory is the repository's own, and its cargo build is the
    # tests' (`--workspace --bins --tests`): the package built alone resolves its dependencies'
    # features differently and compiles the core and the nodes a second time (minutes of CPU,
    # gigabytes of CI disk); this way colcon finds every binary built and installs it.
    ln -sfn "$REPO/target" "$WS/build/$PKG"
    # colcon-ros-cargo writes .cargo/config.toml into colcon's working directory: keep it in $WS.
    # colcon-cargo echoes `cargo metadata`'s JSON: keep colcon's output in a log, shown on failure.
    (cd "$WS" && PATH="$VENV/bin:$PATH" "$VENV/bin/colcon" --log-base log build \
        --paths "$REPO/nodes" --build-base build --install-base install \
        --cargo-args --locked --offline --workspace --bins --tests) > "$WS/colcon_build.log" 2>&1 \
        || { tail -c 3000 "$WS/colcon_build.log" >&2; echo "colcon: 0 passed, 1 failed"; exit 1; }
    grep -E '^(Finished|Summary)' "$WS/colcon_build.log" || true
    check "package in the ament index" \
        test -f "$INSTALL/share/ament_index/resource_index/packages/$PKG"
    for bin in suite predictor forces projection prediction query; do
        check "lib/$PKG/constraint_dynamics_$bin" test -x "$INSTALL/lib/$PKG/constraint_dynamics_$bin"
    done
    for file in package.xml launch/suite.launch.py params/default.yaml params/namespaced.yaml \
        params/suite_mobile_manipulator.yaml urdf/mobile_manipulator.urdf; do
        check "share/$PKG/$file" test -f "$SHARE/$file"
    done
    check "suite --help" "$INSTALL/lib/$PKG/constraint_dynamics_suite" --help > /dev/null
    check "launch file compiles" "$PEER_VENV/bin/python" -m py_compile "$SHARE/launch/suite.launch.py"
    # What the launch file resolves: the share directory through ament_index, as launch_ros does.
    check "ament_index finds the package" env AMENT_PREFIX_PATH="$INSTALL" "$PEER_VENV/bin/python" -c "
import os, sys
from ament_index_python.packages import get_package_prefix, get_package_share_directory
share = get_package_share_directory('$PKG')
exe = os.path.join(get_package_prefix('$PKG'), 'lib', '$PKG', 'constraint_dynamics_suite')
sys.exit(0 if os.path.samefile(share, '$SHARE') and os.access(exe, os.X_OK) else 1)"
    finish
    ;;
run)
    [[ -x "$INSTALL/lib/$PKG/constraint_dynamics_suite" ]] || { echo "colcon: run 'build' first" >&2; exit 1; }
    log=$(mktemp)
    # From a directory that is not the repository: relative paths must resolve next to the
    # installed parameter file, not in a source tree. Bounded: SIGINT after 4 s, SIGKILL (a failure) 2 s later.
    (cd /tmp && timeout --preserve-status -k 2 -s INT 4 "$INSTALL/lib/$PKG/constraint_dynamics_suite" \
        --ros-args --params-file "$SHARE/params/default.yaml" --log-level info > "$log" 2>&1) \
        && status=0 || status=$?
    check "installed suite stops cleanly on SIGINT within 4 s (status $status)" test "$status" -eq 0
    check "installed suite loads the installed scene" grep -q "$SHARE/params/suite_mobile_manipulator.yaml" "$log"
    if [[ $failed -ne 0 ]]; then tail -20 "$log" >&2; fi
    rm -f "$log"
    finish
    ;;
*)
    echo "usage: $0 setup|build|run" >&2
    exit 2
    ;;
esac
