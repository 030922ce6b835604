#!/usr/bin/env bash
# Long fuzzing run: every proptest fuzz target -- the core's tests/it/refusals/fuzz_hostile.rs and
# the nodes' nodes/tests/it/fuzz_requests.rs (handlers without DDS; no participant is opened) and the
# CLI's file parsers (cli/src/fuzz_tests.rs) -- in a
# loop with a new seed per round and PROPTEST_CASES large, at nice 19, until MINUTES are up.
# Prints per target the rounds, cases, failures and elapsed time; exits non-zero on any failure.
# Usage: tools/fuzz_long.sh MINUTES [CASES_PER_ROUND (default 4096)]
set -uo pipefail
cd "$(dirname "$0")/.."
minutes=${1:?usage: tools/fuzz_long.sh MINUTES [CASES]}
cases=${2:-4096}
start=$(date +%s)
# "name cargo-test-arguments" per target.
targets=("fuzz_hostile -p constraint_dynamics --test it refusals::fuzz_hostile::"
    "fuzz_requests -p constraint_dynamics_nodes --test it fuzz_requests::"
    "cli_fuzz_files -p constraint_dynamics_cli --bin constraint_dynamics fuzz_tests")
for t in "${targets[@]}"; do
    read -r _ args <<<"$t"
    # shellcheck disable=SC2086
    nice -n 19 cargo test --release --offline --no-run $args -q || exit 2
done
end=$(($(date +%s) + minutes * 60)) # the clock starts after the build
declare -A rounds ran failed secs
for t in "${targets[@]}"; do rounds[$t]=0; ran[$t]=0; failed[$t]=0; secs[$t]=0; done
log=$(mktemp /tmp/fuzz_long.XXXXXX)
seed=$(( $(date +%s) % 1000000 ))
while (($(date +%s) < end)); do
    for t in "${targets[@]}"; do
        left=$((end - $(date +%s)))
        ((left > 0)) || break
        read -r test args <<<"$t"
        seed=$((seed + 1))
        t0=$(date +%s)
        # A round that would outlast the deadline is cut by timeout (not counted as a failure).
        PROPTEST_CASES=$cases PROPTEST_RNG_SEED=$seed timeout --signal=TERM "$left" nice -n 19 \
            cargo test --release --offline -q $args >"$log" 2>&1
        rc=$?
        secs[$t]=$((secs[$t] + $(date +%s) - t0))
        if ((rc == 124)); then
            echo "$test: seed $seed cut at the deadline"
            continue
        fi
        n=$(grep -hE '^test result:' "$log" | awk '{p += $4 + $6} END {print p + 0}')
        rounds[$t]=$((rounds[$t] + 1))
        ran[$t]=$((ran[$t] + n * cases))
        if ((rc != 0)); then
            failed[$t]=$((failed[$t] + 1))
            echo "$test: FAILED with PROPTEST_RNG_SEED=$seed PROPTEST_CASES=$cases:"
            grep -E 'panicked|minimal failing input|Test failed|^test .* FAILED' "$log" | head -20
        else
            echo "$test: seed $seed, $n targets x $cases cases ok"
        fi
    done
done
rm -f "$log"
status=0
for t in "${targets[@]}"; do
    read -r test _ <<<"$t"
    echo "fuzz_long: $test: ${rounds[$t]} rounds, ${ran[$t]} cases, ${failed[$t]} failed, ${secs[$t]} s"
    ((failed[$t] == 0)) || status=1
done
echo "fuzz_long: $(($(date +%s) - start)) s elapsed, $([[ $status -eq 0 ]] && echo ok || echo FAILURES)"
exit $status
