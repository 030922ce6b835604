#!/usr/bin/env bash
# The floor under the 2 s horizon of the mobile manipulator (its 10 ms budget), in compiled Pinocchio:
# RK4 at 1 ms over 2 s with no constraints at all (tools/peers/horizon_pin.cpp).
#   tools/peers/horizon_floor.sh [RUNS]
# Uses the pinned venv of tools/robots/setup_venv.sh ($CD_ANCHORS_VENV, else .venv-anchors) and
# ../shared/tools/anchors/cpp/build.sh's compiler flags; the binary is cached in target/anchors.
# Compare with `cargo bench --bench horizon -- horizon/mobile_manipulator` run right after, on the
# same otherwise idle machine (docs/performance.md, "The 2 s horizon of the mobile manipulator").
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
venv=${CD_ANCHORS_VENV:-$root/.venv-anchors}
out=$root/target/anchors
# The anchors' build makes (or reuses) the venv and the headers the wheel omits.
"$root/../shared/tools/anchors/cpp/build.sh" "$venv" "$out" > /dev/null
P=$(ls -d "$venv"/lib/python3*/site-packages/cmeel.prefix | head -1)
src=$root/tools/peers/horizon_pin.cpp
sum=$(sha256sum "$src" | cut -c1-16)
bin=$out/horizon_pin
if [ ! -x "$bin" ] || [ "$(cat "$bin.sha" 2>/dev/null)" != "$sum" ]; then
  DEFS="-DNDEBUG -DBOOST_MPL_LIMIT_LIST_SIZE=30 -DBOOST_MPL_LIMIT_VECTOR_SIZE=30 -DBOOST_MPL_CFG_NO_PREPROCESSED_HEADERS \
    -DBOOST_FUSION_INVOKE_MAX_ARITY=12 -DPINOCCHIO_WITH_URDFDOM -DPINOCCHIO_URDFDOM_HEADERS_MAJOR_VERSION=3 \
    -DPINOCCHIO_URDFDOM_HEADERS_MINOR_VERSION=0 -DPINOCCHIO_URDFDOM_HEADERS_PATCH_VERSION=0"
  INC="-I$P/include -I$P/include/eigen3 -I$P/include/urdfdom_headers -I$P/include/urdfdom"
  LIBS="-L$P/lib -Wl,-rpath,$P/lib -lpinocchio_parsers -lpinocchio_default -lurdfdom_model -lboost_filesystem -lboost_serialization"
  g++ -std=c++17 -O3 $DEFS -DPINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION $INC "$src" -o "$bin" $LIBS >&2
  echo "$sum" > "$bin.sha"
fi
"$bin" "$root/urdf/mobile_manipulator.urdf" "${1:-30}"
