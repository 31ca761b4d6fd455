#!/usr/bin/env bash
# pipetrack's CPU twins against OpenCV's version of the same early-vision
# chain: one thread each, measured back to back in one run, with the ratios.
#
#   benches/vs_opencv.sh [--opencv PROGRAM] [--sizes 256x242,640x480,1280x720]
#                        [--rounds 3] [--seconds 0.4] [--iters 100]
#
# PROGRAM (or the OPENCV_EV_BENCH environment variable; the option wins) is an
# OpenCV timing program that takes `--iters N --warm N --threads 1 --sizes WxH
# --csv FILE` and writes one CSV line per operation and size:
# `op,width,height,threads,median_ms,min_ms,...`, with the rows `gauss5_s1.0`,
# `tdiff_thr`, `sobel_mag_ori`, `log_gl`, `zc_loop`, `cpf_loop` and `chain`
# compared below. Without one, the script says so and prints pipetrack's
# figures alone. PIPETRACK names the pipetrack binary (default: this
# checkout's release build, built first).
#
# Each round runs, for every size, the OpenCV program and then pipetrack's
# CPU benchmark (`RAYON_NUM_THREADS=1`, no GPU). Both report the fastest of
# many calls; a stage's figure is its best over the rounds. On a machine
# shared with other processes that is the figure least disturbed by them.
# A second table sets pipetrack's whole chain against the sum of the stage
# rows it runs (every stage of `pipetrack bench`).
set -euo pipefail

opencv="${OPENCV_EV_BENCH:-}"
sizes="256x242,640x480,1280x720"
rounds=3
seconds=0.4
iters=100
while [ $# -gt 0 ]; do
    case "$1" in
        --opencv) opencv="$2"; shift 2 ;;
        --sizes) sizes="$2"; shift 2 ;;
        --rounds) rounds="$2"; shift 2 ;;
        --seconds) seconds="$2"; shift 2 ;;
        --iters) iters="$2"; shift 2 ;;
        -h|--help) sed -n '2,22p' "$0"; exit 0 ;;
        *) echo "vs_opencv.sh: unknown argument $1 (see --help)" >&2; exit 2 ;;
    esac
done

root="$(cd "$(dirname "$0")/.." && pwd)"
pipetrack="${PIPETRACK:-}"
if [ -z "$pipetrack" ]; then
    (cd "$root" && cargo build --release --quiet)
    pipetrack="$root/target/release/pipetrack"
fi

if [ -n "$opencv" ] && [ -x "$opencv" ]; then
    have_opencv=1
else
    have_opencv=0
    if [ -n "$opencv" ]; then
        echo "OpenCV program not found or not executable: $opencv; pipetrack's figures only" >&2
    else
        echo "OpenCV program not given (--opencv or OPENCV_EV_BENCH); pipetrack's figures only" >&2
    fi
fi

work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

# pipetrack stage, the OpenCV row that computes the same, and what each does.
pairs="gaussian:gauss5_s1.0 temporal_diff:tdiff_thr sobel:sobel_mag_ori log:log_gl zero_crossing:zc_loop cpf:cpf_loop"
stages="gaussian,temporal_diff,frame_sum,sobel,compaction,log,zero_crossing,cpf,edge_pyramid,chain"

for round in $(seq "$rounds"); do
    for size in ${sizes//,/ }; do
        echo "round $round/$rounds, $size" >&2
        if [ "$have_opencv" = 1 ]; then
            "$opencv" --iters "$iters" --warm 10 --threads 1 --sizes "$size" --csv "$work/cv.csv" >/dev/null 2>&1
            # op ms (fastest call)
            awk -F, -v s="$size" 'NR > 1 { print s, $1, $6 }' "$work/cv.csv" >>"$work/opencv"
        fi
        RAYON_NUM_THREADS=1 "$pipetrack" bench --cpu-only --sizes "$size" --stages "$stages" \
            --seconds "$seconds" | awk '$2 ~ /^[0-9]+x[0-9]+$/ { print $2, $1, $NF }' >>"$work/ours"
    done
done

# Best (smallest) figure per size and operation over the rounds.
best() { awk '{ k = $1 " " $2; if (!(k in m) || $3 + 0 < m[k]) m[k] = $3 + 0 } END { for (k in m) print k, m[k] }' "$1"; }
best "$work/ours" >"$work/ours.best"
if [ "$have_opencv" = 1 ]; then best "$work/opencv" >"$work/opencv.best"; else : >"$work/opencv.best"; fi

awk -v sizes="$sizes" -v pairs="$pairs" -v have_opencv="$have_opencv" '
    FILENAME ~ /ours.best$/ { ours[$1, $2] = $3; next }
    { cv[$1, $2] = $3 }
    END {
        n = split(sizes, size, ",")
        m = split(pairs, pair, " ")
        print "| size | pipetrack stage | ms | OpenCV row | ms | pipetrack / OpenCV |"
        print "|---|---|---:|---|---:|---:|"
        for (i = 1; i <= n; i++) {
            s = size[i]; sum = 0; cvsum = 0; slower = 0
            for (j = 1; j <= m; j++) {
                split(pair[j], p, ":")
                t = ours[s, p[1]]; sum += t
                if (have_opencv) {
                    c = cv[s, p[2]]; cvsum += c
                    r = t / c; if (r > 1) slower++
                    printf "| %s | %s | %.3f | %s | %.3f | %.2f |\n", s, p[1], t, p[2], c, r
                } else {
                    printf "| %s | %s | %.3f | %s | - | - |\n", s, p[1], t, p[2]
                }
            }
            if (have_opencv) {
                printf "| %s | **sum of the six** | **%.3f** | chain | %.3f | **%.2f** |\n", s, sum, cv[s, "chain"], sum / cv[s, "chain"]
                printf "| %s | (sum of the six) | %.3f | sum of the six rows | %.3f | %.2f |\n", s, sum, cvsum, sum / cvsum
                verdict[s] = sprintf("%s: %d of %d stages slower than OpenCV; sum / OpenCV chain = %.2f (target <= 0.80)", s, slower, m, sum / cv[s, "chain"])
            } else {
                printf "| %s | **sum of the six** | **%.3f** | chain | - | - |\n", s, sum
            }
        }
        print ""
        print "| size | pipetrack chain ms | sum of its stage rows ms | chain / sum |"
        print "|---|---:|---:|---:|"
        for (i = 1; i <= n; i++) {
            s = size[i]
            all = ours[s, "gaussian"] + ours[s, "temporal_diff"] + ours[s, "frame_sum"] + ours[s, "sobel"] \
                + ours[s, "compaction"] + ours[s, "log"] + ours[s, "zero_crossing"] + ours[s, "cpf"] \
                + ours[s, "edge_pyramid"]
            printf "| %s | %.3f | %.3f | %.2f |\n", s, ours[s, "chain"], all, ours[s, "chain"] / all
        }
        if (have_opencv) {
            print ""
            for (i = 1; i <= n; i++) print verdict[size[i]]
        } else {
            print ""
            print "OpenCV was not found: no ratios."
        }
    }
' "$work/ours.best" "$work/opencv.best"
