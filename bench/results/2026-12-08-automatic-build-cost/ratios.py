"""Per pair the automatic / d = 2/3 cm ratios of CPU time (user + system) and wall time; min / median / max.

Usage: ratios.py times.csv  (columns pair,build,core,wall_s,user_s,system_s,max_rss_kb)
"""
import csv
import statistics
import sys

# /usr/bin/time puts "Command exited with non-zero status N" before the figures of a build that exits non-zero
# (drape_db build exits 4 when hold points failed); those lines are not rows.
rows = [r for r in csv.DictReader(open(sys.argv[1])) if r["pair"].isdigit()]
pairs = sorted({r["pair"] for r in rows})
cpu, wall = [], []
print("pair,auto_cpu_s,d067_cpu_s,cpu_ratio,auto_wall_s,d067_wall_s,wall_ratio")
for p in pairs:
    by = {r["build"]: r for r in rows if r["pair"] == p}
    if set(by) != {"auto", "d067"}:
        continue
    c = {k: float(v["user_s"]) + float(v["system_s"]) for k, v in by.items()}
    w = {k: float(v["wall_s"]) for k, v in by.items()}
    cpu.append(c["auto"] / c["d067"])
    wall.append(w["auto"] / w["d067"])
    print(f"{p},{c['auto']:.1f},{c['d067']:.1f},{cpu[-1]:.3f},{w['auto']:.1f},{w['d067']:.1f},{wall[-1]:.3f}")
for name, v in (("cpu", cpu), ("wall", wall)):
    print(f"# {name} ratio over {len(v)} pairs: min {min(v):.3f} median {statistics.median(v):.3f} max {max(v):.3f}")
