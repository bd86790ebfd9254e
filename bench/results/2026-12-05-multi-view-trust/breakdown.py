#!/usr/bin/env python3
"""Why located corners miss: per evidence and number of images, the located corners of foreign_corners.csv
split into ok (within 3 cm of the truth of their name), wrong_name (within 3 cm of another true corner),
not_a_corner (on the true cloth, > 3 cm from every true corner: a fold's bottom or an edge) and off_cloth.
Usage: breakdown.py DIR/foreign_corners.csv ..."""
import collections, csv, sys

for path in sys.argv[1:]:
    counts = collections.Counter()
    for r in csv.DictReader(open(path)):
        if r['evidence'] not in ('lowest_point', 'outline_corner'):
            continue
        e, c, s = float(r['error_m']), float(r['any_truth_corner_m']), float(r['truth_surface_m'])
        kind = 'ok' if e <= 0.03 else 'wrong_name' if c <= 0.03 else 'off_cloth' if s > 0.02 else 'not_a_corner'
        counts[(r['evidence'], r['views'], kind)] += 1
    print(path)
    for key in sorted(counts):
        print('  %-15s %s image(s) %-13s %3d' % (key[0], key[1], key[2], counts[key]))
