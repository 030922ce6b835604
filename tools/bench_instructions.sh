#!/usr/bin/env bash
# Instruction counts of the core's criterion bench routines at two commits, and their ratio:
#   tools/bench_instructions.sh OLD_REV NEW_REV [BENCH ...]   (default: every [[bench]] of NEW_REV)
# criterion's --test mode runs each routine once; callgrind counts only inside Bencher::iter (every
# thread), so setup is left out and the count is the same from run to run whatever else the machine
# does: mostly to the instruction, within 1e-4 where the routine reads the clock (Clarabel's timers)
# and 3e-4 with worker threads (the rollouts, the covariance's worker). All routines of a bench run
# in one process: a routine's count can differ by a few 1e-3 from a run of that routine alone (the
# allocator's state).
# Each commit is checked out in a worktree under target/bench_instructions and built there with
# the bench profile (the first build takes minutes) into $CARGO_TARGET_DIR, else
# target/bench_instructions/target. A bench missing at OLD_REV is counted at NEW_REV only and
# listed as new. The dynamics and chain benches read example-robot-data from $CD_ANCHORS_VENV,
# else .venv-anchors of this checkout or of the main worktree (tools/robots/setup_venv.sh).
# Counts are kept per commit and bench in target/bench_instructions/COMMIT.BENCH.txt; a rerun
# measures again only what is missing there (delete a file to measure it again).
set -euo pipefail
REPO=$(cd "$(dirname "$0")/.." && pwd)
[[ $# -ge 2 ]] || { echo "usage: $0 OLD_REV NEW_REV [BENCH ...]" >&2; exit 2; }
old=$(git -C "$REPO" rev-parse --verify "$1^{commit}")
new=$(git -C "$REPO" rev-parse --verify "$2^{commit}")
shift 2
if [[ $# -gt 0 ]]; then
    benches=("$@")
else
    read -r -a benches <<< "$(git -C "$REPO" show "$new:Cargo.toml" |
        awk '/^\[\[bench\]\]/ {b = 1; next}
             b && /^name *=/ {gsub(/[" ]/, ""); sub(/name=/, ""); print; b = 0}' |
        tr '\n' ' ')"
fi
WORK=$REPO/target/bench_instructions
export CARGO_TARGET_DIR=${CARGO_TARGET_DIR:-$WORK/target}
if [[ -z ${CD_ANCHORS_VENV:-} ]]; then
    main_wt=$(dirname "$(cd "$REPO" && realpath "$(git rev-parse --git-common-dir)")")
    for v in "$REPO/.venv-anchors" "$main_wt/.venv-anchors"; do
        [[ -d $v ]] && { export CD_ANCHORS_VENV=$v; break; }
    done
fi
mkdir -p "$WORK"
# The benches read ../shared/reference beside the checkout: the worktrees' is this checkout's.
if [[ ! -e $WORK/shared && -d $REPO/../shared ]]; then
    ln -s "$(realpath "$REPO/../shared")" "$WORK/shared"
fi
count() { # count COMMIT: "bench|routine|instructions" lines into $WORK/COMMIT.BENCH.txt
    local rev=$1 wt=$WORK/wt-$1 b present=() todo=() args=()
    for b in "${benches[@]}"; do
        git -C "$REPO" cat-file -e "$rev:benches/$b.rs" 2> /dev/null || continue
        present+=("$b")
        [[ -s $WORK/$rev.$b.txt ]] || todo+=("$b")
    done
    [[ ${#todo[@]} -gt 0 ]] || return 0
    [[ -d $wt ]] || git -C "$REPO" worktree add --detach "$wt" "$rev" > /dev/null
    for b in "${todo[@]}"; do args+=(--bench "$b"); done
    # The executables of this commit's benches, as cargo names them (not the newest file: the
    # other commit's binaries sit in the same target directory).
    (cd "$wt" && cargo bench -p constraint_dynamics --no-run --offline \
        --message-format=json-render-diagnostics "${args[@]}") |
        jq -r 'select(.reason == "compiler-artifact" and .executable != null)
            | "\(.target.name) \(.executable)"' > "$WORK/$rev.bins"
    for b in "${todo[@]}"; do
        local bin out=$WORK/$rev.$b.txt
        bin=$(awk -v b="$b" '$1 == b {print $2}' "$WORK/$rev.bins")
        [[ -x $bin ]] || { echo "no executable for bench $b at $rev" >&2; exit 1; }
        local names dumps routines
        names=$("$bin" --list | sed -n 's/: benchmark$//p') ||
            { echo "bench $b --list failed at $rev" >&2; exit 1; }
        # One run of every routine; callgrind zeroes its counts when Bencher::iter is entered and
        # writes a profile when it returns (cg.N, N = 1, 2, ... in the order of --list), so the
        # setup runs once and is left out, and the routine's worker threads are counted too.
        rm -f "$WORK/cg.$rev".*
        valgrind --tool=callgrind --callgrind-out-file="$WORK/cg.$rev" \
            '--zero-before=criterion::bencher::Bencher<M>::iter' \
            '--dump-after=criterion::bencher::Bencher<M>::iter' "$bin" --test \
            > "$WORK/cg.$rev.log" 2>&1 ||
            { echo "bench $b failed at $rev:" >&2; tail -5 "$WORK/cg.$rev.log" >&2; exit 1; }
        dumps=$(find "$WORK" -maxdepth 1 -name "cg.$rev.[0-9]*" | wc -l)
        routines=$(wc -l <<< "$names")
        [[ $dumps -eq $routines ]] ||
            { echo "bench $b at $rev: $dumps profiles for $routines routines" >&2; exit 1; }
        local k=0
        while IFS= read -r n; do
            k=$((k + 1))
            echo "$b|$n|$(awk '/^(summary|totals):/ {print $2; exit}' "$WORK/cg.$rev.$k")"
        done <<< "$names" > "$out.part"
        mv "$out.part" "$out"
    done
}
count "$old"
count "$new"
python3 - "$WORK" "$old" "$new" "${benches[@]}" <<'PY'
import os, sys
work, old_rev, new_rev, benches = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4:]
def load(rev):
    counts = {}
    for b in benches:
        path = os.path.join(work, f"{rev}.{b}.txt")
        if os.path.exists(path):
            for line in open(path):
                bench, name, n = line.rstrip("\n").split("|")
                counts[(bench, name)] = int(n)
    return counts
old, new = load(old_rev), load(new_rev)
rows = sorted(((new[k] / old[k], k) for k in old.keys() & new.keys()), reverse=True)
for ratio, (bench, name) in rows:
    print(f"{ratio:7.4f}  {bench}: {name}  {old[(bench, name)]} -> {new[(bench, name)]}")
for bench, name in sorted(new.keys() - old.keys()):
    print(f"    new  {bench}: {name}  {new[(bench, name)]}")
for bench, name in sorted(old.keys() - new.keys()):
    print(f"   gone  {bench}: {name}  {old[(bench, name)]}")
if rows:
    print(f"{len(rows)} routines at both, instructions new/old: max {rows[0][0]:.4f}, "
          f"min {rows[-1][0]:.4f}; {len(new.keys() - old.keys())} new, "
          f"{len(old.keys() - new.keys())} gone")
PY
