#!/usr/bin/env bash
# The `lowe` tracker over a sweep of rendered scenes and seeds, on the CPU
# backend: one line per run with what `pipetrack score` reports (frames
# tracking, false tracking, mean corner error, joint error), then the
# totals. With two binaries, both track every scene and each line shows
# the first's figures → the second's.
#
#   benches/lowe_sweep.sh [--seeds "0 1 2"] [--jobs N] [--scratch DIR] [--config FILE] BINARY [BINARY2]
#
# Scenes (300 frames each, 640×480): the hinged box with noise σ 8 at
# 20 px/frame; at 20, 25 and 30 px/frame; with half the visible edges
# hidden at 10, 20 and 30 px/frame; and the box at 20, 25 and 30 px/frame
# and half hidden at 10 and 20 px/frame. Each scene is rendered once per seed
# by the first binary (`synth`); --jobs runs that many tracks at a time
# (default: the number of cores). Runs whose false tracking exceeds 1 % of
# their frames are marked `!` (for either binary); a run whose track or
# score failed shows `failed`, the tool's message in its score file under
# --scratch. --config passes a tracker configuration (TOML, as `track
# --config`) to every run of every binary.
set -euo pipefail

seeds="0 1 2"
jobs=$(nproc)
scratch=""
config=""
binaries=()
while [ $# -gt 0 ]; do
    case "$1" in
        --seeds) seeds="$2"; shift 2 ;;
        --jobs) jobs="$2"; shift 2 ;;
        --scratch) scratch="$2"; shift 2 ;;
        --config) config="$2"; shift 2 ;;
        -h|--help) sed -n '2,20p' "$0"; exit 0 ;;
        *) binaries+=("$1"); shift ;;
    esac
done
if [ ${#binaries[@]} -lt 1 ] || [ ${#binaries[@]} -gt 2 ]; then
    echo "lowe_sweep.sh: name one or two pipetrack binaries" >&2
    exit 2
fi
for b in "${binaries[@]}"; do
    [ -x "$b" ] || { echo "lowe_sweep.sh: $b: not an executable" >&2; exit 2; }
done
config_args=()
if [ -n "$config" ]; then
    [ -f "$config" ] || { echo "lowe_sweep.sh: $config: not a file" >&2; exit 2; }
    config_args=(--config "$(cd "$(dirname "$config")" && pwd)/$(basename "$config")")
fi
if [ -z "$scratch" ]; then
    scratch=$(mktemp -d)
    trap 'rm -rf "$scratch"' EXIT
fi
mkdir -p "$scratch"

# name|synth arguments
scenes=(
    "hinged-box noise 8, 20 px/frame|hinged-box --speed 20 --noise 8"
    "hinged-box 20 px/frame|hinged-box --speed 20"
    "hinged-box 25 px/frame|hinged-box --speed 25"
    "hinged-box 30 px/frame|hinged-box --speed 30"
    "hinged-box half hidden, 10 px/frame|hinged-box --speed 10 --occlude 0.5"
    "hinged-box half hidden, 20 px/frame|hinged-box --speed 20 --occlude 0.5"
    "hinged-box half hidden, 30 px/frame|hinged-box --speed 30 --occlude 0.5"
    "box 20 px/frame|box --speed 20"
    "box 25 px/frame|box --speed 25"
    "box 30 px/frame|box --speed 30"
    "box half hidden, 10 px/frame|box --speed 10 --occlude 0.5"
    "box half hidden, 20 px/frame|box --speed 20 --occlude 0.5"
)

runs=()
for i in "${!scenes[@]}"; do
    args=${scenes[$i]#*|}
    for seed in $seeds; do
        dir="$scratch/scene$i-seed$seed"
        if [ ! -d "$dir" ]; then
            # shellcheck disable=SC2086
            if ! out=$("${binaries[0]}" synth $args --seed "$seed" "$dir" 2>&1); then
                echo "$out" >&2
                exit 2
            fi
        fi
        runs+=("$i $seed")
    done
done

# Track and score every run with every binary, `jobs` at a time.
for b in "${!binaries[@]}"; do
    printf '%s\n' "${runs[@]}" | xargs -P "$jobs" -L 1 bash -c '
        bin=$0; scratch=$1; b=$2; i=$4; seed=$5; config_args=()
        [ -n "$3" ] && config_args=(--config "$3")
        dir="$scratch/scene$i-seed$seed"
        if "$bin" track "$dir" --tracker lowe --backend cpu "${config_args[@]}" --out "$dir.$b.jsonl" 2> "$dir.$b.score"; then
            "$bin" score "$dir" "$dir.$b.jsonl" > "$dir.$b.score" 2>&1 || true
        fi
    ' "${binaries[$b]}" "$scratch" "$b" "${config_args[1]:-}"
done

# One score file's figures: tracked false mean_px joint_mean joint_max
# (zeros and `failed` when it holds no score).
figures() {
    awk '
        /^frames tracked:/ { tracked = $3 }
        /^false tracking:/ { false_ = $3 }
        /^mean corner error:/ { mean = $4 }
        /^joint error:/ { jm = $3; jx = $5 }
        END {
            if (tracked == "" || false_ == "") { print "0 0 failed - -"; exit }
            printf "%s %s %s %s %s\n", tracked, false_, (mean == "" ? "-" : mean), (jm == "" ? "-" : jm), (jx == "" ? "-" : jx)
        }
    ' "$1"
}

printf '%-38s %4s  %-22s %-10s %-14s %s\n' "scene" "seed" "tracking (false)" "mean px" "joint mean°" "joint max°"
totals=("0 0" "0 0")
for run in "${runs[@]}"; do
    read -r i seed <<< "$run"
    name=${scenes[$i]%%|*}
    cells=("" "" "" "" "")
    mark=""
    for b in "${!binaries[@]}"; do
        read -r tracked false_ mean jm jx < <(figures "$scratch/scene$i-seed$seed.$b.score")
        [ "$false_" -gt 3 ] && mark="!"
        totals[b]="$(( ${totals[b]%% *} + tracked )) $(( ${totals[b]##* } + false_ ))"
        new=("$tracked ($false_)" "$mean" "${jm%°}" "${jx%°}")
        for k in 0 1 2 3; do
            cells[k]="${cells[k]:+${cells[k]} → }${new[k]}"
        done
    done
    printf '%-38s %4s  %-22s %-10s %-14s %s %s\n' "$name" "$seed" "${cells[0]}" "${cells[1]}" "${cells[2]}" "${cells[3]}" "$mark"
done
for b in "${!binaries[@]}"; do
    read -r tracked false_ <<< "${totals[b]}"
    echo "total, ${binaries[$b]}: $tracked frames tracking, $false_ false ($(( ${#runs[@]} )) runs of 300 frames)"
done
