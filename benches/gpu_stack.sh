#!/usr/bin/env bash
# Stacked sequences on a real GPU, in one run: the device and driver, the
# shader parity tests (GPU against CPU twins, `GpuStack` against the CPU
# backend per sequence) when their test binary is given, and the whole
# chain with K sequences in flight beside the same K stacked
# (`pipetrack bench --lanes`, rows `chain xK` and `chain stacked xK`), at
# 640x480, 1280x720 and 1920x1080, again with every list capped at 1500
# features (`--cap 1500`, as the blue tracker caps its list) at the two
# smaller sizes, then the single-stream stage rows at 640x480.
#
#   OUT=results benches/gpu_stack.sh [path/to/pipetrack] [path/to/parity-test-binary]
#
# Needs a Vulkan loader (libvulkan1) and the vendor's Vulkan driver; check
# the adapter printed first. Results go to $OUT (default gpu_results):
# device.txt, parity.txt, lanes_<size>[_cap1500].json, bench.json and log.txt.
set -uo pipefail

BIN=$(realpath "${1:-target/release/pipetrack}")
PARITY=${2:+$(realpath "$2")}
OUT=$(realpath -m "${OUT:-gpu_results}")
mkdir -p "$OUT"
LOG="$OUT/log.txt"
: >"$LOG"
say() { echo "== $(date +%T) $*" | tee -a "$LOG"; }

say "device"
{
    nvidia-smi --query-gpu=name,driver_version,memory.total,clocks.max.sm --format=csv 2>&1 || echo "no nvidia-smi"
    echo "cpu cores: $(nproc)"
    "$BIN" --version
} | tee "$OUT/device.txt"

if [ -n "$PARITY" ]; then
    say "parity tests"
    PIPETRACK_REQUIRE_GPU=1 timeout 90 "$PARITY" --test-threads 1 >"$OUT/parity.txt" 2>&1
    echo "parity exit status $?" | tee -a "$LOG"
    tail -n 3 "$OUT/parity.txt" | tee -a "$LOG"
fi

for run in "640x480 1,8,16,32,64" "1280x720 1,8,64" "1920x1080 1,8,16" \
    "640x480 1,8,16,32,64 1500" "1280x720 1,8,64 1500"; do
    set -- $run
    say "bench: chain with $2 sequences in flight and stacked at $1${3:+, lists capped at $3}"
    timeout 120 "$BIN" bench --json --lanes "$2" --sizes "$1" ${3:+--cap "$3"} --seconds 0.3 \
        >"$OUT/lanes_$1${3:+_cap$3}.json" 2>>"$LOG"
    echo "exit status $?" >>"$LOG"
done

say "bench: stages at 640x480"
timeout 80 "$BIN" bench --json --sizes 640x480 --seconds 0.3 >"$OUT/bench.json" 2>>"$LOG"

say "summary"
for f in "$OUT"/lanes_*.json; do
    grep -m1 '"adapter"' "$f"
    grep -o '"stage": "chain[^"]*",\|"size": "[^"]*",\|"cpu_fps": [0-9.]*\|"gpu_fps": [0-9.a-z]*\|"host_ms": [0-9.]*\|"stacked": [a-z]*\|"dispatches_per_step": [0-9]*' "$f" |
        paste -sd' ' | sed 's/"stage"/\n"stage"/g; s/"size"/\n"size"/g'
done | tee -a "$LOG"
