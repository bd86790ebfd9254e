#!/usr/bin/env python3
"""Ratios after/before of the interleaved runs in runs.csv (run.sh): per configuration and thread count,
min / median / max over the rounds of wall(after) / wall(before), and of wall(2 threads) / wall(1 thread)
per binary. Prints a Markdown table."""
import csv, statistics, sys
from collections import defaultdict

rows = list(csv.DictReader(open(sys.argv[1] if len(sys.argv) > 1 else "runs.csv")))
wall = defaultdict(dict)  # (model, integrator, spacing, threads) -> {(round, binary): wall}
for r in rows:
    if r["integrator"] == "reference":
        continue
    key = (r["model"], r["integrator"], r["spacing_m"], r["threads"])
    wall[key][(r["trial"], r["binary"])] = float(r["wall_s"])

def mmm(v):
    return "%.2f / %.2f / %.2f" % (min(v), statistics.median(v), max(v))

print("| model | integrator | d [m] | threads | after / before | 2 / 1 threads, before | 2 / 1 threads, after |")
print("|---|---|---|---|---|---|---|")
for key in sorted(wall):
    model, integ, d, t = key
    rounds = sorted({rnd for rnd, _ in wall[key]})
    ab = [wall[key][(n, "after")] / wall[key][(n, "before")] for n in rounds]
    if t == "2":
        one = wall[(model, integ, d, "1")]
        tb = [wall[key][(n, "before")] / one[(n, "before")] for n in rounds]
        ta = [wall[key][(n, "after")] / one[(n, "after")] for n in rounds]
        print(f"| {model} | {integ} | {d} | {t} | {mmm(ab)} | {mmm(tb)} | {mmm(ta)} |")
    else:
        print(f"| {model} | {integ} | {d} | {t} | {mmm(ab)} | | |")
