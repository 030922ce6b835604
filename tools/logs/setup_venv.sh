#!/usr/bin/env bash
# Create (or reuse) the pinned "logs" venv: MuJoCo (the independent simulator of the recorded
# test logs) and the MCAP writer with its ROS 2 (CDR) support. tools/logs/make_logs.py writes
# tests/data/logs/ with it; the tests read the committed files and need no venv, except
# tools/logs/check_evaluate.py (the independent recomputation of `evaluate`'s figures).
#
#   tools/logs/setup_venv.sh [VENV_DIR]
#
# VENV_DIR defaults to $CD_LOGS_VENV, else REPO/.venv-logs (gitignored). A stamp file records
# the pins; when it matches, nothing is done. Opens no DDS participant. Needs python3 and PyPI.
set -euo pipefail

HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
REPO=$(cd "$HERE/../.." && pwd)
VENV=${1:-${CD_LOGS_VENV:-$REPO/.venv-logs}}
PYTHON=${PYTHON:-python3}
PINS=(mujoco==3.14.0 mcap==1.6.0 mcap-ros2-support==0.6.0 zstandard==0.25.0 numpy==2.4.6 PyYAML==6.0.3)

STAMP="$VENV/.cd_logs_stamp"
WANT=$(printf '%s\n' "stamp-v1" "$("$PYTHON" -c 'import sys; print(sys.version.split()[0])')" "${PINS[@]}")
if [[ ! ( -f "$STAMP" && "$(cat "$STAMP")" == "$WANT" && -x "$VENV/bin/python" ) ]]; then
    rm -f "$STAMP"
    [[ -x "$VENV/bin/python" ]] || "$PYTHON" -m venv "$VENV"
    "$VENV/bin/python" -m pip install --disable-pip-version-check -q "${PINS[@]}"
    printf '%s\n' "$WANT" > "$STAMP"
fi
"$VENV/bin/python" - <<'PY'
import mujoco, mcap_ros2
print(f"setup_venv: MuJoCo {mujoco.__version__}, mcap-ros2-support {mcap_ros2.__version__}")
PY
