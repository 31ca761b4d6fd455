#!/usr/bin/env bash
# pipetrack's `lowe` tracker against ViSP's model-based edge tracker
# (vpMbEdgeTracker) on the same sequence folders, one thread each, scored
# by `pipetrack score` against each folder's truth.jsonl.
#
#   benches/vs_visp.sh [--visp PROGRAM] [--rounds N] [--work DIR] SEQ[:SETTINGS.xml] ...
#
# PROGRAM (or VISP_EDGE_TRACKER; the option wins) is benches/visp/edge_tracker.cpp
# built by benches/visp/build.sh. SETTINGS is a ViSP tracker settings file
# (moving edges, clipping; e.g. a data set's Config/NAME.xml) for that
# sequence; without it ViSP's tracker keeps its defaults. PIPETRACK names the
# pipetrack binary (default: this checkout's release build, built first).
# A sequence is a folder with truth.jsonl: `synth box` (the rigid box; ViSP's
# tracker has no joints) or `import-visp` of a data set with truth. Needs
# python3 (benches/visp/prepare.py: the model in ViSP's format and its
# vertices in pipetrack's order).
#
# Per sequence and tracker (benches/visp/row.py): frames reported tracking,
# false tracking (more than 5 px off), mean and median corner error
# (`pipetrack score`), and the median and mean milliseconds per frame of the tracker's own timing: `ms` of
# `track` (early vision and tracking, RAYON_NUM_THREADS=1) and the time of
# vpMbEdgeTracker::track (OMP_NUM_THREADS=1), frame reading excluded in both,
# the first frame (initialisation) left out. With --rounds N (default 1) both
# trackers run N times, alternately, and each row shows the round with the
# lowest median; the rounds' outputs must agree but for `ms`. A sequence
# named twice (with two ViSP settings) gets one pipetrack row.
set -euo pipefail

visp="${VISP_EDGE_TRACKER:-}"
rounds=1
work=""
seqs=()
while [ $# -gt 0 ]; do
    case "$1" in
        --visp) visp="$2"; shift 2 ;;
        --rounds) rounds="$2"; shift 2 ;;
        --work) work="$2"; shift 2 ;;
        -h|--help) sed -n '2,26p' "$0"; exit 0 ;;
        -*) echo "vs_visp.sh: unknown option $1 (see --help)" >&2; exit 2 ;;
        *) seqs+=("$1"); shift ;;
    esac
done
if [ ${#seqs[@]} -eq 0 ]; then
    echo "vs_visp.sh: name at least one sequence folder (see --help)" >&2
    exit 2
fi
if ! [ "$rounds" -ge 1 ] 2>/dev/null; then
    echo "vs_visp.sh: --rounds takes a whole number from 1 (got $rounds)" >&2
    exit 2
fi
if [ -z "$visp" ] || [ ! -x "$visp" ]; then
    echo "vs_visp.sh: ViSP's edge tracker not found (--visp or VISP_EDGE_TRACKER; build it with benches/visp/build.sh)" >&2
    exit 2
fi

root="$(cd "$(dirname "$0")/.." && pwd)"
pipetrack="${PIPETRACK:-}"
if [ -z "$pipetrack" ]; then
    (cd "$root" && cargo build --release --quiet)
    pipetrack="$root/target/release/pipetrack"
fi
if [ -z "$work" ]; then
    work="$(mktemp -d)"
    trap 'rm -rf "$work"' EXIT
fi

echo "| sequence | tracker | frames tracking | false tracking | mean corner error | median | ms per frame, median / mean |"
echo "|---|---|---|---:|---:|---:|---:|"
# The sequences pipetrack has tracked.
declare -A tracked
index=0
for spec in "${seqs[@]}"; do
    seq="${spec%%:*}"
    settings=()
    if [ "$spec" != "$seq" ]; then settings=(--settings "${spec#*:}"); fi
    index=$((index + 1))
    dir="$work/$index-$(basename "$seq")"
    mkdir -p "$dir"
    if ! args="$(python3 "$root/benches/visp/prepare.py" "$seq" "$dir/visp" 2>"$dir/prepare.log")"; then
        echo "| $(basename "$seq") | — | skipped: $(tail -1 "$dir/prepare.log") | | | | |"
        continue
    fi
    ours=()
    if [ -z "${tracked[$seq]:-}" ]; then ours=("$dir/pipetrack"); tracked[$seq]=1; fi
    for round in $(seq "$rounds"); do
        # shellcheck disable=SC2086 # the ten numbers are separate arguments
        OMP_NUM_THREADS=1 "$visp" "$seq/frames" "$dir/visp/model.cao" "$dir/visp/vertices.txt" \
            "$dir/visp.$round.jsonl" $args "${settings[@]}" >"$dir/visp.log" 2>&1
        for out in "${ours[@]}"; do
            RAYON_NUM_THREADS=1 "$pipetrack" track "$seq" --tracker lowe --backend cpu \
                --out "$out.$round.jsonl" 2>"$dir/pipetrack.log"
        done
    done
    label="ViSP edge"
    if [ ${#settings[@]} -gt 0 ]; then label="ViSP edge (${settings[1]##*/})"; fi
    if [ ${#ours[@]} -gt 0 ]; then
        python3 "$root/benches/visp/row.py" "$pipetrack" "$seq" "pipetrack lowe" "$dir"/pipetrack.*.jsonl
    fi
    python3 "$root/benches/visp/row.py" "$pipetrack" "$seq" "$label" "$dir"/visp.*.jsonl
done
