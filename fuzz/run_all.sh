#!/usr/bin/env bash
# Run every cargo-fuzz target for SECONDS each (default 600), JOBS targets
# at a time (default 1), from its seeds and its corpus, and print one line
# per target: runs, seconds, corpus size and whether libFuzzer reported a
# finding (a crash, a timeout of more than 10 s on one input, or more than
# 2 GB of memory). Needs nightly and cargo-fuzz (README.md).
#
#   fuzz/run_all.sh [SECONDS] [JOBS] [TARGET ...]
#
# Each target's libFuzzer log is kept in logs/<target>.log; findings are
# saved under artifacts/<target>/.
set -euo pipefail
cd "$(dirname "$0")"
seconds=${1:-600}
jobs=${2:-1}
shift $(( $# < 2 ? $# : 2 ))
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
    mapfile -t targets < <(cargo +nightly fuzz list)
fi
cargo +nightly fuzz build >/dev/null
mkdir -p logs
printf '%s\n' "${targets[@]}" | xargs -P "$jobs" -I{} bash -c '
    t={}; mkdir -p corpus/$t
    if cargo +nightly fuzz run "$t" "corpus/$t" "seeds/$t" -- \
        -max_total_time='"$seconds"' -timeout=10 -rss_limit_mb=2048 -max_len=262144 \
        -print_final_stats=1 > "logs/$t.log" 2>&1; then verdict=clean; else verdict="FINDING (logs/$t.log)"; fi
    runs=$(grep -o "stat::number_of_executed_units: *[0-9]*" "logs/$t.log" | grep -o "[0-9]*$" | tail -1)
    secs=$(grep -o "Done [0-9]* runs in [0-9]* second" "logs/$t.log" | grep -o "in [0-9]*" | grep -o "[0-9]*" | tail -1)
    printf "%-20s %12s runs %6s s %6s inputs in corpus  %s\n" "$t" "${runs:-?}" "${secs:-?}" "$(ls corpus/$t | wc -l)" "$verdict"
'
