#!/usr/bin/env python3
"""Median processing time per recognition of each run A<k>, B<k> (here A = colour rendered in the depth fits,
B = depth-only renders) and the B/A ratio per interleaved pair (PAIRS, default "123"). Writes summary.csv.
Usage: summarize.py (in the directory with the runs)."""
import csv, os, statistics

def medians(run, views):
    rows = [r for r in csv.DictReader(open(run + '/foreign_drapes.csv')) if r['views'] == views]
    return statistics.median(float(r['processing_ms']) for r in rows), statistics.median(float(r['refine_ms']) for r in rows)

with open('summary.csv', 'w') as f:
    f.write('pair,views,a_ms,b_ms,ratio_b_over_a,a_refine_ms,b_refine_ms\n')
    for k in os.environ.get('PAIRS', '123'):
        for v in '12':
            (a, ar), (b, br) = medians('A' + k, v), medians('B' + k, v)
            f.write('%s,%s,%.1f,%.1f,%.3f,%.1f,%.1f\n' % (k, v, a, b, b / a, ar, br))
            print('pair %s, %s image(s): A %.0f ms, B %.0f ms, B/A %.3f' % (k, v, a, b, b / a))
