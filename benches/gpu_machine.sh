#!/usr/bin/env bash
# The measurements BENCHMARKS.md records for a real GPU, in one run: the
# device and driver, `pipetrack bench` stage by stage at three sizes, the
# whole chain with 1, 8 and 64 sequences in flight, the window energy, and
# `batch` over a few hundred synthetic sequences with --jobs 1, 8 and 64
# (GPU) beside the CPU backend, then single-sequence `track` times (lowe on
# the box at 4 and 20 px/frame, the box half hidden and the hinged box).
#
#   OUT=results benches/gpu_machine.sh [path/to/pipetrack]
#
# Needs a Vulkan loader (libvulkan1) and the vendor's Vulkan driver; the
# adapter `bench` reports is printed first, so a run on llvmpipe is seen at
# once. SCALE=small runs everything on a few sequences (a check of the
# script itself, e.g. on lavapipe). BASELINE=path/to/another/pipetrack
# times that build too, in the same run, for the chain with sequences in
# flight and the GPU batches (lanes_baseline.json, lines marked "baseline"
# in batch.txt) and its pyramid and chain rows at the three sizes
# (bench_baseline.json). ROUNDS (default 2) is how many times each batch
# runs. Results go to $OUT (default gpu_results): device.txt,
# bench.json, lanes.json, windows.json, batch.txt, track.txt and log.txt
# (with BASELINE also bench_baseline.json and lanes_baseline.json); a short
# summary is printed last.
set -uo pipefail

BIN=$(realpath "${1:-target/release/pipetrack}")
BASE=${BASELINE:+$(realpath "$BASELINE")}
OUT=$(realpath -m "${OUT:-gpu_results}")
SCALE=${SCALE:-full}
ROUNDS=${ROUNDS:-2}
mkdir -p "$OUT"
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
LOG="$OUT/log.txt"
: >"$LOG"
say() { echo "== $(date +%T) $*" | tee -a "$LOG"; }

if [ "$SCALE" = small ]; then
    SIZES=256x242,320x240
    LANE_SIZES=256x242
    LANES=1,4
    SECONDS_PER=0.1
    PENDULA=6
    TARGETS=4
    JOBS="1 4"
    TRACK_FRAMES=20
else
    SIZES=640x480,1280x720,1920x1080
    LANE_SIZES=640x480,1280x720
    LANES=1,8,64
    SECONDS_PER=0.3
    PENDULA=256
    TARGETS=192
    JOBS="1 8 64"
    TRACK_FRAMES=300
fi

say "device"
{
    nvidia-smi --query-gpu=name,driver_version,memory.total,clocks.max.sm,pstate --format=csv 2>&1 || echo "no nvidia-smi"
    echo "cpu cores: $(nproc)"
    "$BIN" --version
} | tee "$OUT/device.txt"

say "bench: stages at $SIZES"
timeout 240 "$BIN" bench --json --sizes "$SIZES" --seconds "$SECONDS_PER" >"$OUT/bench.json" 2>>"$LOG"
grep -m1 '"adapter"' "$OUT/bench.json" | tee -a "$LOG"
if [ -n "$BASE" ]; then
    say "baseline bench: pyramids and the chain at $SIZES"
    timeout 120 "$BASE" bench --json --sizes "$SIZES" --seconds "$SECONDS_PER" --stages cpf,edge_pyramid,chain >"$OUT/bench_baseline.json" 2>>"$LOG"
fi

say "bench: chain with $LANES sequences in flight at $LANE_SIZES"
timeout 240 "$BIN" bench --json --lanes "$LANES" --sizes "$LANE_SIZES" --seconds "$SECONDS_PER" >"$OUT/lanes.json" 2>>"$LOG"
if [ -n "$BASE" ]; then
    say "baseline bench: chain with $LANES sequences in flight"
    timeout 240 "$BASE" bench --json --lanes "$LANES" --sizes "$LANE_SIZES" --seconds "$SECONDS_PER" >"$OUT/lanes_baseline.json" 2>>"$LOG"
fi

say "bench: window energy"
timeout 60 "$BIN" bench --json --windows 200,1000,5000 --seconds "$SECONDS_PER" >"$OUT/windows.json" 2>>"$LOG"

say "synth: $PENDULA pendulum (256x242, 20 frames) and $TARGETS target3dof (640x480, 15 frames) sequences"
mkdir -p "$WORK/p" "$WORK/t"
seq 0 $((PENDULA - 1)) | xargs -P "$(nproc)" -I{} "$BIN" synth pendulum "$WORK/p/s{}" --frames 20 --seed {} >/dev/null 2>>"$LOG"
seq 0 $((TARGETS - 1)) | xargs -P "$(nproc)" -I{} "$BIN" synth target3dof "$WORK/t/s{}" --frames 15 --seed {} >/dev/null 2>>"$LOG"

# One batch run: its last stderr line carries sequences/s and frames/s.
run_batch() { # name manifest tracker backend jobs [binary]
    rm -rf "$WORK/out"
    local line
    line=$(timeout 120 "${6:-$BIN}" batch "$2" --out "$WORK/out" --tracker "$3" --backend "$4" --jobs "$5" 2>&1 >/dev/null | tail -n 1)
    echo "${6:+baseline }$1 $3 backend=$4 jobs=$5: $line" | tee -a "$OUT/batch.txt"
}
: >"$OUT/batch.txt"
for round in $(seq 1 "$ROUNDS"); do
    say "batch round $round"
    for k in $JOBS; do
        run_batch pendulum "$WORK/p" motion-edge gpu "$k"
        run_batch target3dof "$WORK/t" blue gpu "$k"
        if [ -n "$BASE" ]; then
            run_batch pendulum "$WORK/p" motion-edge gpu "$k" "$BASE"
            run_batch target3dof "$WORK/t" blue gpu "$k" "$BASE"
        fi
    done
    run_batch pendulum "$WORK/p" motion-edge cpu "$(nproc)"
    run_batch target3dof "$WORK/t" blue cpu "$(nproc)"
done

say "track: one sequence at a time"
: >"$OUT/track.txt"
"$BIN" synth pendulum "$WORK/tp" --speed 3.9 --frames "$TRACK_FRAMES" >/dev/null 2>>"$LOG"
"$BIN" synth target3dof "$WORK/tt" --speed 0.3 --frames "$TRACK_FRAMES" >/dev/null 2>>"$LOG"
"$BIN" synth box "$WORK/tb" --speed 4 --frames "$TRACK_FRAMES" >/dev/null 2>>"$LOG"
"$BIN" synth box "$WORK/tb20" --speed 20 --frames "$TRACK_FRAMES" >/dev/null 2>>"$LOG"
"$BIN" synth box "$WORK/tbh" --speed 4 --occlude 0.5 --frames "$TRACK_FRAMES" >/dev/null 2>>"$LOG"
"$BIN" synth hinged-box "$WORK/th" --speed 4 --frames "$TRACK_FRAMES" >/dev/null 2>>"$LOG"
# The CPU backend on every core, then on one thread (RAYON_NUM_THREADS=1).
for backend in gpu cpu cpu1; do
    threads=$([ "$backend" = cpu1 ] && echo 1 || nproc)
    for run in "tp motion-edge" "tt blue" "tb lowe" "tb20 lowe" "tbh lowe" "th lowe"; do
        set -- $run
        line=$(RAYON_NUM_THREADS=$threads timeout 120 "$BIN" track "$WORK/$1" --tracker "$2" \
            --backend "${backend%1}" --out "$WORK/o.jsonl" 2>&1 | tail -n 1)
        echo "$2 $1 backend=$backend: $line" | tee -a "$OUT/track.txt"
    done
done

say "summary"
for f in "$OUT"/lanes*.json; do
    echo "$(basename "$f"):"
    grep -o '"stage": "chain[^"]*",\|"size": "[^"]*",\|"cpu_fps": [0-9.]*\|"gpu_fps": [0-9.a-z]*\|"host_ms": [0-9.]*' "$f" | paste -sd' ' | sed 's/"stage"/\n"stage"/g'
done | tee -a "$LOG"
cat "$OUT/batch.txt"
