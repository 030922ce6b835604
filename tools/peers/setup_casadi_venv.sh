#!/usr/bin/env bash
# Create (or reuse) the pinned CasADi venv: the stiff-mechanism peer of the work-precision report
# (tools/peers/andrews_casadi.py: SUNDIALS CVODES and IDAS, as bundled in PyPI `casadi`, on
# generated and compiled C code).
#
#   tools/peers/setup_casadi_venv.sh [VENV_DIR]
#
# VENV_DIR defaults to $CD_CASADI_VENV, else REPO/.venv-casadi (gitignored). A stamp file records
# the pins; when it matches, nothing is done (no network). Needs python3 (3.11 tested), PyPI
# access on the first run, and a C compiler (gcc, or $CC) for the generated code. Prints one line
# with the versions; exits non-zero when the venv cannot be made.
set -euo pipefail
trap 'echo "setup_casadi_venv: failed at line $LINENO: the CasADi peer needs python3 with venv, and PyPI access on its first run" >&2' ERR

HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
REPO=$(cd "$HERE/../.." && pwd)
VENV=${1:-${CD_CASADI_VENV:-$REPO/.venv-casadi}}
PYTHON=${PYTHON:-python3}
PINS=(casadi==3.8.2 numpy==2.4.6)

STAMP="$VENV/.cd_casadi_stamp"
WANT=$(printf '%s\n' "stamp-v1" "$("$PYTHON" -c 'import sys; print(sys.version.split()[0])')" "${PINS[@]}")
if [[ ! ( -f "$STAMP" && "$(cat "$STAMP")" == "$WANT" && -x "$VENV/bin/python" ) ]]; then
    rm -f "$STAMP"
    [[ -x "$VENV/bin/python" ]] || "$PYTHON" -m venv "$VENV"
    "$VENV/bin/python" -m pip install --disable-pip-version-check -q "${PINS[@]}"
    printf '%s\n' "$WANT" > "$STAMP"
fi
"$VENV/bin/python" -c 'import casadi, numpy; print(f"setup_casadi_venv: casadi {casadi.__version__}, numpy {numpy.__version__}")'
