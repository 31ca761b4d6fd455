#!/bin/bash
# Track every sequence of a manifest on a Slurm job array: each array task
# takes its own shard (`--shard I/N`, I = the task's index, N = the number of
# tasks), so the tasks split the manifest exactly and need no coordinator.
# Every task writes into the same output folder (on a shared file system).
#
#   sbatch --export=ALL,MANIFEST=/data/manifest.txt,OUT=/data/tracked examples/batch/slurm.sh
#
# Arguments after the script name go to `pipetrack batch` unchanged, e.g.
# `sbatch examples/batch/slurm.sh --tracker motion-edge`.
#
# Each task adds its lines to OUT/summary.jsonl (under a lock, so tasks
# that end together keep each other's lines). A task killed part-way (time
# limit, pre-emption) is simply run again: it skips the sequences whose
# output is complete. Or, once every task has ended,
#
#   pipetrack batch "$MANIFEST" --out "$OUT" [the same arguments, e.g. --tracker motion-edge]
#
# (no --shard) tracks whatever is still missing; as a follow-up job:
# `sbatch --dependency=afterany:<job id> ...`.
#
#SBATCH --job-name=pipetrack-batch
#SBATCH --array=0-3
#SBATCH --gpus=1
#SBATCH --cpus-per-task=8
#SBATCH --time=04:00:00
#SBATCH --output=pipetrack-batch-%A_%a.log

set -euo pipefail
: "${MANIFEST:=manifest.txt}"
: "${OUT:=tracked}"

exec pipetrack batch "$MANIFEST" --out "$OUT" --jobs 8 \
    --shard "$SLURM_ARRAY_TASK_ID/$SLURM_ARRAY_TASK_COUNT" "$@"
