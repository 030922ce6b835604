#!/usr/bin/env bash
# Instruction counts of the core's criterion bench routines at two commits, and their ratio:
#   tools/bench_instructions.sh OLD_REV NEW_REV [BENCH ...]   (default: every [[bench]] of NEW_REV)
# criterion's --test mode runs each routine once; callgrind counts only inside Bencher::iter*, so
# setup is left out and the count is the same from run to run whatever else the machine does.
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
        awk '/^\[\[bench\]\]/ {b = 1; next} b && /^name *=/ {gsub(/[" ]/, ""); sub(/name=/, ""); print; b = 0}' |
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
[[ -e $WORK/shared || ! -d $REPO/../shared ]] || ln -s "$(realpath "$REPO/../shared")" "$WORK/shared"
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
        --message-format=json-render-diagnostics "${args[@]}") | jq -r 'select(.reason == "compiler-artifact" and .executable != null)
            | "\(.target.name) \(.executable)"' > "$WORK/$rev.bins"
    for b in "${todo[@]}"; do
        local bin out=$WORK/$rev.$b.txt
        bin=$(awk -v b="$b" '$1 == b {print $2}' "$WORK/$rev.bins")
        [[ -x $bin ]] || { echo "no executable for bench $b at $rev" >&2; exit 1; }
        local names
        names=$("$bin" --list) || { echo "bench $b --list failed at $rev" >&2; exit 1; }
        sed -n 's/: benchmark$//p' <<< "$names" | while IFS= read -r n; do
            valgrind --tool=callgrind --callgrind-out-file="$WORK/cg.out" --collect-atstart=no \
                '--toggle-collect=*Bencher*iter*' "$bin" --test --exact "$n" > "$WORK/cg.log" 2>&1 ||
                { echo "$b: $n failed at $rev:" >&2; tail -5 "$WORK/cg.log" >&2; exit 1; }
            echo "$b|$n|$(awk '/^(summary|totals):/ {print $2; exit}' "$WORK/cg.out")"
        done > "$out.part"
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
