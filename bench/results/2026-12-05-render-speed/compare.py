#!/usr/bin/env python3
"""Compares two foreign_drape_bench runs on the same held-out drapes, recognition by recognition (variant,
hold point, views, azimuth): hold-point and corner errors and the processing time per number of images.
Usage: compare.py OLD_DIR NEW_DIR (each with foreign_drapes.csv)."""
import csv, sys, statistics as st
def load(d):
    rows = list(csv.DictReader(open(d + '/foreign_drapes.csv')))
    return rows
def key(r): return (r['variant'], r['hold_x_m'], r['hold_y_m'], r['views'], r['azimuth_deg'])
a = {key(r): r for r in load(sys.argv[1])}
b = {key(r): r for r in load(sys.argv[2])}
common = sorted(set(a) & set(b))
print('common', len(common), 'only A', len(set(a)-set(b)), 'only B', len(set(b)-set(a)))
for v in ('1', '2'):
    ks = [k for k in common if k[3] == v]
    for f, th in (('hold_error_m', .05), ('lowest_corner_error_m', .03), ('best_corner_error_m', .03), ('mean_corner_error_m', None)):
        ea = [float(a[k][f]) for k in ks if a[k]['success'] == '1']
        eb = [float(b[k][f]) for k in ks if b[k]['success'] == '1']
        s = f'views {v} {f}: median {st.median(ea)*100:.2f} -> {st.median(eb)*100:.2f} cm'
        if th: s += f'; within {th*100:.0f} cm {sum(e<=th for e in ea)} -> {sum(e<=th for e in eb)} of {len(ks)}'
        print(s)
    ch = sum(1 for k in ks if abs(float(a[k]['hold_error_m']) - float(b[k]['hold_error_m'])) > 1e-9)
    print(f'views {v}: hold error changed in {ch} of {len(ks)}; processing median {st.median(float(a[k]["processing_ms"]) for k in ks):.0f} -> {st.median(float(b[k]["processing_ms"]) for k in ks):.0f} ms')
