#!/usr/bin/env python3
"""Ratios new/old of the interleaved yarn_step_bench runs of run.sh (min / median / max over rounds)."""
import csv, glob, os, statistics, sys

here = sys.argv[1]
for integrator in ("semi_implicit", "newton"):
    rows = {}  # (arm, round) -> {(side, threads): row}
    for path in glob.glob(os.path.join(here, integrator, "*-*", "step_cost.csv")):
        arm, rnd = os.path.basename(os.path.dirname(path)).split("-")
        with open(path) as f:
            for row in csv.DictReader(f):
                rows.setdefault((arm, rnd), {})[(int(row["side"]), int(row["threads"]))] = row
    keys = sorted({k for d in rows.values() for k in d})
    rounds = sorted({r for (_, r) in rows})
    print(f"{integrator}:")
    for key in keys:
        old = [float(rows[("old", r)][key]["us_per_crossing_step"]) for r in rounds if ("old", r) in rows]
        new = [float(rows[("new", r)][key]["us_per_crossing_step"]) for r in rounds if ("new", r) in rows]
        ratios = sorted(n / o for n, o in zip(new, old))
        its = {arm: sorted({rows[(arm, r)][key]["solver_iterations_per_step"] for r in rounds}) for arm in ("old", "new")}
        print(f"  side {key[0]} ({key[0] ** 2} crossings), {key[1]} thread(s): old {statistics.median(old):.1f}, "
              f"new {statistics.median(new):.1f} us per crossing-step (medians); new/old min {ratios[0]:.3f} "
              f"median {statistics.median(ratios):.3f} max {ratios[-1]:.3f}; solver iterations per step old {its['old']} new {its['new']}")
