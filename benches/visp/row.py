#!/usr/bin/env python3
"""One row of benches/vs_visp.sh's table.

    row.py PIPETRACK SEQ NAME ROUND.jsonl ...

Of the rounds' output lines of one tracker on the sequence folder SEQ (they
must agree but for `ms`), the round with the lowest median `ms` is scored by
`PIPETRACK score SEQ ROUND.jsonl`; the row gives the frames tracking, the
false tracking, the mean and median corner error and that round's median and
mean `ms` (the first frame, the initialisation, left out). A failure is a
row that says what failed.
"""
import json
import os
import re
import statistics
import subprocess
import sys


def main():
    pipetrack, seq, name, rounds = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4:]
    label = os.path.basename(seq.rstrip("/"))
    runs = []
    for path in rounds:
        lines = [json.loads(line) for line in open(path) if line.strip()]
        ms = [line.pop("ms") for line in lines][1:]
        runs.append((statistics.median(ms) if ms else 0.0, statistics.mean(ms) if ms else 0.0, path, lines))
    if any(run[3] != runs[0][3] for run in runs):
        print(f"| {label} | {name} | the rounds' outputs differ | | | | |")
        return
    median, mean, path, _ = min(runs)
    scored = subprocess.run([pipetrack, "score", seq, path], capture_output=True, text=True)
    if scored.returncode != 0:
        print(f"| {label} | {name} | score failed: {scored.stderr.strip()} | | | | |")
        return

    def field(what):
        found = re.search(rf"^{what}:\s+(.*)$", scored.stdout, re.M)
        return found.group(1) if found else "-"

    print(f"| {label} | {name} | {field('frames tracked')} | {field('false tracking').split(' (')[0]} "
          f"| {field('mean corner error')} | {field('median corner error')} | {median:.2f} / {mean:.2f} |")


main()
