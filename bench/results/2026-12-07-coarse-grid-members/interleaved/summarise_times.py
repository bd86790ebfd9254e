#!/usr/bin/env python3
"""Per-hold-point cost ratios from probe.sh's times_*.csv: d = 1 cm base over d = 2/3 cm, and d = 1 cm base plus
soft_light over d = 2/3 cm (min / median / max, and the ratio of the sums). Usage: summarise_times.py times_*.csv"""
import csv
import statistics
import sys

rows = [r for p in sys.argv[1:] for r in csv.DictReader(open(p))]
ref = [float(r['d067_s']) for r in rows]
base = [float(r['d1_base_s']) for r in rows]
both = [float(r['d1_base_s']) + float(r['d1_soft_light_s']) for r in rows]
for name, arm in (('d = 1 cm base', base), ('d = 1 cm base + soft_light', both)):
    ratios = sorted(a / b for a, b in zip(arm, ref))
    print('%s over d = 2/3 cm, %d hold points: min %.2f median %.2f max %.2f; sums %.0f s / %.0f s = %.2f' % (
        name, len(ratios), ratios[0], statistics.median(ratios), ratios[-1], sum(arm), sum(ref), sum(arm) / sum(ref)))
