#!/usr/bin/env bash
# Per-frame time of `pipetrack track --backend cpu` on one thread, for two or
# more pipetrack binaries side by side: the median of the `ms` field of each
# output line (early vision and the tracker's own work; reading the PNG
# frames is not in it), the binaries run alternately in each round.
#
#   benches/track_times.sh [--rounds 3] [--scratch DIR] BINARY...
#
# Each BINARY tracks two scenes rendered once by the first binary:
# `synth pendulum` (256×242, 200 frames) with `motion-edge` and
# `synth target3dof` (640×480, 300 frames) with `blue`, both at their
# defaults. To compare with an older tree, build it in a worktree:
#
#   git worktree add /tmp/pipetrack-old <commit>
#   (cd /tmp/pipetrack-old && cargo build --release)
#   cargo build --release
#   benches/track_times.sh /tmp/pipetrack-old/target/release/pipetrack target/release/pipetrack
set -euo pipefail

rounds=3
scratch=""
binaries=()
while [ $# -gt 0 ]; do
    case "$1" in
        --rounds) rounds="$2"; shift 2 ;;
        --scratch) scratch="$2"; shift 2 ;;
        -h|--help) sed -n '2,17p' "$0"; exit 0 ;;
        *) binaries+=("$1"); shift ;;
    esac
done
if [ ${#binaries[@]} -eq 0 ]; then
    echo "track_times.sh: name at least one pipetrack binary" >&2
    exit 2
fi
for b in "${binaries[@]}"; do
    [ -x "$b" ] || { echo "track_times.sh: $b: not an executable" >&2; exit 2; }
done
if [ -z "$scratch" ]; then
    scratch=$(mktemp -d)
    trap 'rm -rf "$scratch"' EXIT
fi
first="${binaries[0]}"
"$first" synth pendulum "$scratch/pendulum" > /dev/null
"$first" synth target3dof "$scratch/target3dof" > /dev/null

median_ms() {
    python3 -c '
import json, statistics, sys
print("%.4f" % statistics.median(json.loads(l)["ms"] for l in open(sys.argv[1])))' "$1"
}

echo "| round | tracker | scene | binary | median ms per frame |"
echo "|---:|---|---|---|---:|"
for round in $(seq 1 "$rounds"); do
    for case in "motion-edge pendulum" "blue target3dof"; do
        set -- $case
        for b in "${binaries[@]}"; do
            RAYON_NUM_THREADS=1 "$b" track "$scratch/$2" --tracker "$1" --backend cpu --out "$scratch/out.jsonl" 2> /dev/null
            echo "| $round | $1 | $2 | $b | $(median_ms "$scratch/out.jsonl") |"
        done
    done
done
