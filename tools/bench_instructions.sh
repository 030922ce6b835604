#!/usr/bin/env bash
# Instruction counts of the core's criterion bench routines at two commits, and their ratio:
#   tools/bench_instructions.sh OLD_REV NEW_REV [BENCH ...]   (default: dynamics envelope horizon)
# criterion's --test mode runs each routine once; callgrind counts only inside Bencher::iter*, so
# setup is left out and the count is the same from run to run whatever else the machine does.
# Each commit is checked out in a worktree under target/bench_instructions and built there with
# the bench profile (the first build takes minutes). The dynamics bench reads example-robot-data
# from .venv-anchors (tools/robots/setup_venv.sh).
set -euo pipefail
REPO=$(cd "$(dirname "$0")/.." && pwd)
[[ $# -ge 2 ]] || { echo "usage: $0 OLD_REV NEW_REV [BENCH ...]" >&2; exit 2; }
old=$1 new=$2
shift 2
benches=("${@:-dynamics envelope horizon}")
read -r -a benches <<< "${benches[*]}"
WORK=$REPO/target/bench_instructions
export CARGO_TARGET_DIR=$WORK/target CD_ANCHORS_VENV=${CD_ANCHORS_VENV:-$REPO/.venv-anchors}
mkdir -p "$WORK"
count() { # count REV: "bench|routine|instructions" lines into $WORK/REV.txt
    local rev=$1 wt=$WORK/wt-$1 out=$WORK/$1.txt
    [[ -d $wt ]] || git -C "$REPO" worktree add --detach "$wt" "$rev" > /dev/null
    local args=()
    for b in "${benches[@]}"; do args+=(--bench "$b"); done
    (cd "$wt" && cargo bench -p constraint_dynamics --no-run --offline "${args[@]}" 2>&1 | tail -1)
    : > "$out"
    for b in "${benches[@]}"; do
        # The newest binary of this bench: the one just built for this commit.
        local bin
        bin=$(ls -t "$CARGO_TARGET_DIR"/release/deps/"$b"-* | grep -v '\.d$' | head -1)
        "$bin" --list 2> /dev/null | sed -n 's/: benchmark$//p' | while IFS= read -r n; do
            valgrind --tool=callgrind --callgrind-out-file="$WORK/cg.out" --collect-atstart=no \
                '--toggle-collect=*Bencher*iter*' "$bin" --test --exact "$n" > /dev/null 2>&1
            echo "$b|$n|$(awk '/^(summary|totals):/ {print $2; exit}' "$WORK/cg.out")" >> "$out"
        done
    done
}
count "$old"
count "$new"
python3 - "$WORK/$old.txt" "$WORK/$new.txt" <<'PY'
import sys
def load(path):
    return {tuple(l.split("|")[:2]): int(l.split("|")[2]) for l in open(path) if l.strip().split("|")[2]}
old, new = load(sys.argv[1]), load(sys.argv[2])
rows = sorted(((new[k] / old[k], k) for k in old.keys() & new.keys()), reverse=True)
for ratio, (bench, name) in rows:
    print(f"{ratio:7.4f}  {bench}: {name}  {old[(bench, name)]} -> {new[(bench, name)]}")
print(f"{len(rows)} routines, instructions new/old: max {rows[0][0]:.4f}, min {rows[-1][0]:.4f}")
PY
