#!/usr/bin/env python3
"""Paired comparison of two foreign_drape_bench row files on the same renders: per number of images and
figure, how many recognitions only the first database gets right, only the second, and both.
Usage: paired.py A.csv B.csv"""
import csv
import sys


def rows(path):
    return {(r['variant'], r['hold_x_m'], r['hold_y_m'], r['views'], r['azimuth_deg']): r for r in csv.DictReader(open(path))}


a, b = rows(sys.argv[1]), rows(sys.argv[2])
figures = [('hold within 5 cm', 'hold_error_m', 0.05), ('lowest corner within 3 cm', 'lowest_corner_error_m', 0.03),
           ('best corner within 3 cm', 'best_corner_error_m', 0.03)]
print('views,figure,only_first,only_second,both,neither')
for views in ('1', '2'):
    keys = [k for k in a if k[3] == views and k in b]
    for name, col, limit in figures:
        def ok(r):
            return r['success'] == '1' and r[col] not in ('', 'nan') and float(r[col]) <= limit
        fa = [ok(a[k]) for k in keys]
        fb = [ok(b[k]) for k in keys]
        print('%s,%s,%d,%d,%d,%d' % (views, name, sum(x and not y for x, y in zip(fa, fb)),
                                     sum(y and not x for x, y in zip(fa, fb)), sum(x and y for x, y in zip(fa, fb)),
                                     sum(not x and not y for x, y in zip(fa, fb))))
