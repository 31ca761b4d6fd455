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
# Per sequence and tracker: frames reported tracking, false tracking (more
# than 5 px off), mean and median corner error (`pipetrack score`), and the
# median and mean milliseconds per frame of the tracker's own timing: `ms` of
# `track` (early vision and tracking, RAYON_NUM_THREADS=1) and the time of
# vpMbEdgeTracker::track (OMP_NUM_THREADS=1), frame reading excluded in both,
# the first frame (initialisation) left out. With --rounds N (default 1) both
# trackers run N times, alternately, and each row shows the round with the
# lowest median; the rounds' outputs must agree but for `ms`.
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

# Of the rounds' output files given, the one with the lowest median `ms`;
# fails when they differ in anything but `ms`.
fastest() {
    python3 - "$@" <<'PY'
import json, statistics, sys
runs = []
for path in sys.argv[1:]:
    lines = [json.loads(line) for line in open(path) if line.strip()]
    ms = [line.pop("ms") for line in lines][1:]
    runs.append((statistics.median(ms) if ms else 0.0, path, lines))
if any(lines != runs[0][2] for _, _, lines in runs):
    sys.exit(f"the rounds' outputs differ: {' '.join(sys.argv[1:])}")
print(min(runs)[1])
PY
}

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
    for round in $(seq "$rounds"); do
        # shellcheck disable=SC2086 # the ten numbers are separate arguments
        OMP_NUM_THREADS=1 "$visp" "$seq/frames" "$dir/visp/model.cao" "$dir/visp/vertices.txt" \
            "$dir/visp.$round.jsonl" $args "${settings[@]}" >"$dir/visp.log" 2>&1
        RAYON_NUM_THREADS=1 "$pipetrack" track "$seq" --tracker lowe --backend cpu \
            --out "$dir/pipetrack.$round.jsonl" 2>"$dir/pipetrack.log"
    done
    label="ViSP edge"
    if [ ${#settings[@]} -gt 0 ]; then label="ViSP edge (${settings[1]##*/})"; fi
    for tracker in pipetrack visp; do
        name="pipetrack lowe"
        if [ "$tracker" = visp ]; then name="$label"; fi
        if best="$(fastest "$dir/$tracker".*.jsonl 2>&1)"; then
            row "$seq" "$name" "$best"
        else
            echo "| $(basename "$seq") | $name | ${best##*: } | | | | |"
        fi
    done
done
