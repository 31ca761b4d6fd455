#!/usr/bin/env bash
# pipetrack's `lowe` tracker against ViSP's model-based edge tracker
# (vpMbEdgeTracker) on the same sequence folders, one thread each, scored
# by `pipetrack score` against each folder's truth.jsonl.
#
#   benches/vs_visp.sh [--visp PROGRAM] [--work DIR] SEQ[:SETTINGS.xml] ...
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
# Per sequence and tracker: frames reported tracking, false tracking (more
# than 5 px off), mean and median corner error (`pipetrack score`), and the
# median and mean milliseconds per frame of the tracker's own timing: `ms` of
# `track` (early vision and tracking, RAYON_NUM_THREADS=1) and the time of
# vpMbEdgeTracker::track (OMP_NUM_THREADS=1), frame reading excluded in both,
# the first frame (initialisation) left out.
set -euo pipefail

visp="${VISP_EDGE_TRACKER:-}"
work=""
seqs=()
while [ $# -gt 0 ]; do
    case "$1" in
        --visp) visp="$2"; shift 2 ;;
        --work) work="$2"; shift 2 ;;
        -h|--help) sed -n '2,23p' "$0"; exit 0 ;;
        -*) echo "vs_visp.sh: unknown option $1 (see --help)" >&2; exit 2 ;;
        *) seqs+=("$1"); shift ;;
    esac
done
if [ ${#seqs[@]} -eq 0 ]; then
    echo "vs_visp.sh: name at least one sequence folder (see --help)" >&2
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

# One table row from a sequence, a tracker's name and its output lines.
row() {
    local seq="$1" name="$2" out="$3" score
    if ! score="$("$pipetrack" score "$seq" "$out" 2>&1)"; then
        echo "| $(basename "$seq") | $name | score failed: $score | | | | |"
        return
    fi
    python3 - "$seq" "$name" "$out" "$score" <<'PY'
import json, re, statistics, sys
seq, name, out, score = sys.argv[1:]
def field(label):
    m = re.search(rf"^{label}:\s+(.*)$", score, re.M)
    return m.group(1) if m else "-"
tracked = field("frames tracked")
false = field("false tracking").split(" (")[0]
ms = [json.loads(line)["ms"] for line in open(out) if line.strip()][1:]
print(f"| {seq.rstrip('/').split('/')[-1]} | {name} | {tracked} | {false} | {field('mean corner error')} "
      f"| {field('median corner error')} | {statistics.median(ms):.2f} / {statistics.mean(ms):.2f} |")
PY
}

echo "| sequence | tracker | frames tracking | false tracking | mean corner error | median | ms per frame, median / mean |"
echo "|---|---|---|---:|---:|---:|---:|"
for spec in "${seqs[@]}"; do
    seq="${spec%%:*}"
    settings=()
    if [ "$spec" != "$seq" ]; then settings=(--settings "${spec#*:}"); fi
    dir="$work/$(basename "$seq")"
    mkdir -p "$dir"
    if ! args="$(python3 "$root/benches/visp/prepare.py" "$seq" "$dir/visp" 2>"$dir/prepare.log")"; then
        echo "| $(basename "$seq") | — | skipped: $(tail -1 "$dir/prepare.log") | | | | |"
        continue
    fi
    # shellcheck disable=SC2086 # the ten numbers are separate arguments
    OMP_NUM_THREADS=1 "$visp" "$seq/frames" "$dir/visp/model.cao" "$dir/visp/vertices.txt" "$dir/visp.jsonl" \
        $args "${settings[@]}" >"$dir/visp.log" 2>&1
    RAYON_NUM_THREADS=1 "$pipetrack" track "$seq" --tracker lowe --backend cpu --out "$dir/pipetrack.jsonl" \
        2>"$dir/pipetrack.log"
    row "$seq" "pipetrack lowe" "$dir/pipetrack.jsonl"
    label="ViSP edge"
    if [ ${#settings[@]} -gt 0 ]; then label="ViSP edge (${settings[1]##*/})"; fi
    row "$seq" "$label" "$dir/visp.jsonl"
done
