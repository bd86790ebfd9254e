#!/usr/bin/env python3
"""How well each property of a located lowest point tells a real corner from a fold's bottom: over the
corner rows of the given directories, the lowest points within 3 cm of their corner ('good') against those
more than 3 cm from every true corner ('fold'), the quartiles of each column and the AUC (the chance that a
random fold row has the larger value; 0.5 = no information). Usage: features.py DIR ..."""
import csv, sys

rows = []
for d in sys.argv[1:]:
    rows += [r for r in csv.DictReader(open(d + '/foreign_corners.csv')) if r['evidence'] == 'lowest_point']
F = lambda r, k: float(r[k])
good = [r for r in rows if F(r, 'error_m') <= .03]
fold = [r for r in rows if F(r, 'any_truth_corner_m') > .03]
print('lowest points: %d within 3 cm, %d more than 3 cm from every true corner, %d other' % (len(good), len(fold), len(rows) - len(good) - len(fold)))
columns = [c for c in ('tip_roughness_m', 'tip_depth_residual_m', 'tip_depth_slope', 'tip_rounding_m', 'tip_angle_deg',
                       'located_shift_m', 'label_margin_m', 'score') if c in rows[0]]
for k in columns:
    def quart(s):
        v = sorted(F(r, k) for r in s)
        return '%.4g / %.4g / %.4g' % (v[len(v) // 4], v[len(v) // 2], v[3 * len(v) // 4])
    auc = sum((F(f, k) > F(g, k)) + 0.5 * (F(f, k) == F(g, k)) for f in fold for g in good) / (len(fold) * len(good))
    print('%-22s good %-28s fold %-28s AUC %.2f' % (k, quart(good), quart(fold), auc))
