#!/usr/bin/env python3
"""Median processing time per recognition of each run (A = commit e231be7, B = commit a5eb8d3 with the shape
fit's reach),
the B/A ratio per interleaved pair and min / median / max over the pairs. Writes summary.csv.
Usage: summarize.py (in this directory)."""
import csv, statistics

def median_ms(run, views):
    rows = [r for r in csv.DictReader(open(run + '/foreign_drapes.csv')) if r['views'] == views]
    return statistics.median(float(r['processing_ms']) for r in rows)

with open('summary.csv', 'w') as f:
    f.write('pair,views,a_ms,b_ms,ratio_b_over_a\n')
    for v in '12':
        ratios = []
        for k in '12345':
            a, b = median_ms('A' + k, v), median_ms('B' + k, v)
            ratios.append(b / a)
            f.write('%s,%s,%.1f,%.1f,%.3f\n' % (k, v, a, b, b / a))
        print('%s image(s): B/A min %.3f, median %.3f, max %.3f' % (v, min(ratios), statistics.median(ratios), max(ratios)))
