#!/usr/bin/env bash
# The stress scenes of motion-edge, blue and condensation on seeds their
# tests do not use, on the CPU backend: one line per run with the frames
# tracking within the false-tracking bound and the frames tracking beyond
# it (`pipetrack score`), runs under 95 % on target or over 1 % false
# marked `!`, then the totals.
#
#   benches/held_out.sh [--jobs N] [--scratch DIR] [--motion-edge-seeds "S …"]
#                       [--blue-seeds "S …"] [--condensation-seeds "S …"] BINARY
#
# motion-edge (pendulum, 200 frames, seeds 1–9): rotating at 16 and
# 20 px/frame, a second object crossing behind the target at 3.9 and
# 16 px/frame. blue (target3dof, 300 frames, seeds 8–12): shaken at 0.6
# and 1.2 rad/s, smooth at 1.2 rad/s. condensation (textured-plane, 200
# frames, seeds 1–6): translation and translation + roll, sampling the
# screw components the motion has. --jobs runs that many at a time
# (default: the number of cores); --scratch keeps the sequences and
# outputs there (default: a temporary folder, removed at the end). The
# --*-seeds options run other seeds ("" leaves that tracker out).
set -euo pipefail

jobs=$(nproc)
scratch=""
binary=""
motion_edge_seeds="1 2 3 4 5 6 7 8 9"
blue_seeds="8 9 10 11 12"
condensation_seeds="1 2 3 4 5 6"
while [ $# -gt 0 ]; do
    case "$1" in
        --jobs) jobs="$2"; shift 2 ;;
        --scratch) scratch="$2"; shift 2 ;;
        --motion-edge-seeds) motion_edge_seeds="$2"; shift 2 ;;
        --blue-seeds) blue_seeds="$2"; shift 2 ;;
        --condensation-seeds) condensation_seeds="$2"; shift 2 ;;
        -h|--help) sed -n '2,20p' "$0"; exit 0 ;;
        *) [ -z "$binary" ] || { echo "held_out.sh: name one pipetrack binary" >&2; exit 2; }; binary="$1"; shift ;;
    esac
done
[ -n "$binary" ] || { echo "held_out.sh: name one pipetrack binary" >&2; exit 2; }
[ -x "$binary" ] || { echo "held_out.sh: $binary: not an executable" >&2; exit 2; }
binary="$(cd "$(dirname "$binary")" && pwd)/$(basename "$binary")"
if [ -z "$scratch" ]; then
    scratch=$(mktemp -d)
    trap 'rm -rf "$scratch"' EXIT
fi
mkdir -p "$scratch"
printf 'component_weights = [1.0, 1.0, 0.0, 0.0, 0.0, 0.0]\n' > "$scratch/translation.toml"
printf 'component_weights = [1.0, 1.0, 0.0, 0.0, 0.0, 1.0]\n' > "$scratch/roll.toml"

# name|tracker|config (or -)|synth arguments, one run per line
runs=()
for s in $motion_edge_seeds; do
    runs+=("motion-edge rotating 16 px/frame, seed $s|motion-edge|-|pendulum --frames 200 --speed 16 --seed $s")
    runs+=("motion-edge rotating 20 px/frame, seed $s|motion-edge|-|pendulum --frames 200 --speed 20 --seed $s")
    runs+=("motion-edge second object 3.9 px/frame, seed $s|motion-edge|-|pendulum --frames 200 --speed 3.9 --seed $s --set distractor=true --set distractor_y=120")
    runs+=("motion-edge second object 16 px/frame, seed $s|motion-edge|-|pendulum --frames 200 --speed 16 --seed $s --set distractor=true --set distractor_y=120")
done
for s in $blue_seeds; do
    runs+=("blue shaken 0.6 rad/s, seed $s|blue|-|target3dof --frames 300 --speed 0.6 --shake --seed $s")
    runs+=("blue shaken 1.2 rad/s, seed $s|blue|-|target3dof --frames 300 --speed 1.2 --shake --seed $s")
    runs+=("blue smooth 1.2 rad/s, seed $s|blue|-|target3dof --frames 300 --speed 1.2 --seed $s")
done
for s in $condensation_seeds; do
    runs+=("condensation translation, seed $s|condensation|translation.toml|textured-plane --set motion=translation --seed $s")
    runs+=("condensation translation + roll, seed $s|condensation|roll.toml|textured-plane --set motion=roll --seed $s")
done

# Render, track and score each run, `jobs` at a time; run k writes $scratch/k.score.
for k in "${!runs[@]}"; do
    IFS='|' read -r _ tracker config args <<< "${runs[$k]}"
    printf '%s\0%s\0%s\0%s\0' "$k" "$tracker" "$config" "$args"
done | xargs -0 -n 4 -P "$jobs" bash -c '
    bin=$0; scratch=$1; k=$2; tracker=$3; config=$4; args=$5
    dir="$scratch/$k"; config_args=()
    [ "$config" != "-" ] && config_args=(--config "$scratch/$config")
    # shellcheck disable=SC2086
    { [ -d "$dir" ] || "$bin" synth $args "$dir" > /dev/null; } 2> "$dir.score" &&
        "$bin" track "$dir" --tracker "$tracker" --backend cpu "${config_args[@]}" --out "$dir.jsonl" 2> "$dir.score" &&
        "$bin" score "$dir" "$dir.jsonl" > "$dir.score" 2>&1 || true
' "$binary" "$scratch"

printf '%-50s %8s %12s %8s\n' "run" "frames" "on target" "false"
total_runs=0
marked=0
for k in "${!runs[@]}"; do
    name=${runs[$k]%%|*}
    read -r frames tracked false_ < <(awk '
        /^frames tracked:/ { tracked = $3; frames = $5 }
        /^false tracking:/ { false_ = $3 }
        END { if (tracked == "" || false_ == "") print "0 0 failed"; else print frames, tracked, false_ }
    ' "$scratch/$k.score")
    total_runs=$((total_runs + 1))
    if [ "$false_" = "failed" ]; then
        printf '%-50s %8s %12s %8s !\n' "$name" "-" "-" "failed"
        marked=$((marked + 1))
        continue
    fi
    on_target=$((tracked - false_))
    mark=""
    if [ $((on_target * 100)) -lt $((frames * 95)) ] || [ $((false_ * 100)) -gt "$frames" ]; then
        mark="!"
        marked=$((marked + 1))
    fi
    printf '%-50s %8s %12s %8s %s\n' "$name" "$frames" "$on_target" "$false_" "$mark"
done
echo "$total_runs runs, $marked under 95 % on target or over 1 % false tracking"
