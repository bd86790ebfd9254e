#!/usr/bin/env python3
"""Headline figures of foreign_drape_bench row files and their paired comparison with a reference on the same
renders: per database and number of images, the share of recognitions with the hold point within 5 cm and the
lowest / best corner within 3 cm, and per figure how many recognitions only the reference gets right, only the
database, and the two-sided sign-test probability of a split at least that uneven by chance.
Usage: summarise.py REFERENCE.csv NAME=ROWS.csv ... > summary.csv"""
import csv
import math
import sys

FIGURES = [('hold_5cm', 'hold_error_m', 0.05), ('lowest_corner_3cm', 'lowest_corner_error_m', 0.03),
           ('best_corner_3cm', 'best_corner_error_m', 0.03)]


def rows(path):
    return {(r['variant'], r['hold_x_m'], r['hold_y_m'], r['views'], r['azimuth_deg']): r
            for r in csv.DictReader(open(path))}


def right(row, column, limit):
    return row['success'] == '1' and row[column] not in ('', 'nan') and float(row[column]) <= limit


def sign_test(k, n):
    """Two-sided exact sign test: probability of a split at least as uneven as k of n under p = 1/2."""
    if n == 0:
        return 1.0
    low = min(k, n - k)
    tail = sum(math.comb(n, i) for i in range(low + 1)) / 2.0 ** n
    return min(1.0, 2 * tail)


reference = rows(sys.argv[1])
print('database,views,figure,share,reference_share,only_reference,only_database,sign_test_p')
for spec in sys.argv[2:]:
    name, path = spec.split('=', 1)
    other = rows(path)
    for views in ('1', '2'):
        keys = [k for k in reference if k[3] == views and k in other]
        for figure, column, limit in FIGURES:
            a = [right(reference[k], column, limit) for k in keys]
            b = [right(other[k], column, limit) for k in keys]
            only_a = sum(x and not y for x, y in zip(a, b))
            only_b = sum(y and not x for x, y in zip(a, b))
            print('%s,%s,%s,%.3f,%.3f,%d,%d,%.3f' % (name, views, figure, sum(b) / len(keys), sum(a) / len(keys),
                                                      only_a, only_b, sign_test(only_a, only_a + only_b)))
