#!/usr/bin/env python3
"""new/old wall-time ratios per round of run.sh, min / median / max, per solver setting."""
import csv, os, statistics, sys

here = sys.argv[1]
times = {}
with open(os.path.join(here, "build_times.csv")) as f:
    for row in csv.DictReader(f):
        times[(row["solves"], row["round"], row["arm"])] = float(row["wall_s"])
for solves in ("default", "fast"):
    rounds = sorted({r for (s, r, _) in times if s == solves})
    ratios = sorted(times[(solves, r, "new")] / times[(solves, r, "old")] for r in rounds)
    old = [times[(solves, r, "old")] for r in rounds]
    new = [times[(solves, r, "new")] for r in rounds]
    print(f"{solves}: old {', '.join(f'{t:.1f}' for t in old)} s; new {', '.join(f'{t:.1f}' for t in new)} s; "
          f"new/old min {ratios[0]:.3f} median {statistics.median(ratios):.3f} max {ratios[-1]:.3f}")
