#!/usr/bin/env python3
"""Summary of drape_build_bench --mode holds rows: the fast arm's wall time over the reference's per hold point
(min / median / max) and summed, the named-point distance to the reference up to a mirror, and how many hold
points fell back to the dynamic run. Usage: summarise_holds.py build_holds*.csv"""
import csv
import statistics
import sys

rows = [r for path in sys.argv[1:] for r in csv.DictReader(open(path))]
ratio = [float(r['fast_s']) / float(r['dynamic_s']) for r in rows]
dist = [float(r['mirror_aware_named_distance_m']) for r in rows]
fell_back = sum(r['fast_method'].startswith('dynamic (') for r in rows)
print('%d hold points; fast / reference wall time min %.2f median %.2f max %.2f, summed %.0f s / %.0f s = %.2f'
      % (len(rows), min(ratio), statistics.median(ratio), max(ratio), sum(float(r['fast_s']) for r in rows),
         sum(float(r['dynamic_s']) for r in rows),
         sum(float(r['fast_s']) for r in rows) / sum(float(r['dynamic_s']) for r in rows)))
print('named points up to a mirror: median %.1f mm, %d within 5 mm, %d within 3 cm, largest %.0f mm; %d fell back'
      % (1000 * statistics.median(dist), sum(d < 0.005 for d in dist), sum(d < 0.03 for d in dist), 1000 * max(dist),
         fell_back))
