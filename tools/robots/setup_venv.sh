#!/usr/bin/env bash
# Create (or reuse) the pinned "anchors" venv: Pinocchio (PyPI `pin`) and example-robot-data,
# the independent references of tests/it/example_robot_data.rs (and of tools/bench.py,
# which uses the same venv). The dataset stays in the venv; nothing is copied into the repo.
#
#   tools/robots/setup_venv.sh [VENV_DIR]
#
# VENV_DIR defaults to $CD_ANCHORS_VENV, else REPO/.venv-anchors (gitignored). A stamp file
# records the pins; when it matches, nothing is done. Prints the robots/ folder of the dataset.
# Opens no DDS participant. Needs python3 (3.11 tested) and PyPI access.
set -euo pipefail

HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
REPO=$(cd "$HERE/../.." && pwd)
VENV=${1:-${CD_ANCHORS_VENV:-$REPO/.venv-anchors}}
PYTHON=${PYTHON:-python3}
PINS=(pin==4.1.0 example-robot-data==6.0.0 numpy==2.4.6)

STAMP="$VENV/.cd_anchors_stamp"
WANT=$(printf '%s\n' "stamp-v1" "$("$PYTHON" -c 'import sys; print(sys.version.split()[0])')" "${PINS[@]}")
if [[ ! ( -f "$STAMP" && "$(cat "$STAMP")" == "$WANT" && -x "$VENV/bin/python" ) ]]; then
    rm -f "$STAMP"
    [[ -x "$VENV/bin/python" ]] || "$PYTHON" -m venv "$VENV"
    "$VENV/bin/python" -m pip install --disable-pip-version-check -q "${PINS[@]}"
    printf '%s\n' "$WANT" > "$STAMP"
fi
"$VENV/bin/python" - <<'PY'
import glob, sys, pinocchio
robots = glob.glob(f"{sys.prefix}/lib/python*/site-packages/cmeel.prefix/share/example-robot-data/robots")
assert robots, "example-robot-data not installed"
n = len(glob.glob(f"{robots[0]}/**/*.urdf", recursive=True))
print(f"setup_venv: Pinocchio {pinocchio.__version__}, {n} URDFs in {robots[0]}")
PY
