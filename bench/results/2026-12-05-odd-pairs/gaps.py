#!/usr/bin/env python3
"""The contradiction test (EvidenceOptions::contradiction_gap) on consistent pairs (both images of one drape,
foreign_drapes.csv, views 2) and odd pairs (the second image of another drape, foreign_odd_pairs.csv):
how often each is flagged, the coverage gaps, and how often an odd pair moves the hold point more than 5 cm
away from the first image's answer, and its safe corners. Usage: gaps.py DIR ..."""
import csv, sys

cons, odd = [], []
for d in sys.argv[1:]:
    cons += [r for r in csv.DictReader(open(d + '/foreign_drapes.csv')) if r['views'] == '2']
    odd += list(csv.DictReader(open(d + '/foreign_odd_pairs.csv')))
F = lambda r, k: float(r[k])
for name, rows in (('consistent pairs', cons), ('odd pairs', odd)):
    flagged = [r for r in rows if int(r['contradicting_images']) > 0]
    alone = [r for r in flagged if F(r, 'coverage_gap') < 0]
    gaps = sorted(F(r, 'coverage_gap') for r in rows if F(r, 'coverage_gap') >= 0 and int(r['contradicting_images']) == 0)
    print('%s: %d, flagged contradicting %d (%.0f %%; answer from the first image alone in %d); gaps of the unflagged: '
          'median %.3f, max %.3f' % (name, len(rows), len(flagged), 100.0 * len(flagged) / len(rows), len(alone),
                                      gaps[len(gaps) // 2], gaps[-1]))
worse = [r for r in odd if F(r, 'hold_error_m') > F(r, 'one_image_hold_error_m') + 0.05]
print('odd pairs whose hold point is > 5 cm worse than the first image alone: %d of %d (flagged: %d)' %
      (len(worse), len(odd), sum(int(r['contradicting_images']) > 0 for r in worse)))
if 'max_image_regret' in odd[0]:
    for name, rows in (('consistent pairs', cons), ('odd pairs', odd)):
        v = sorted(F(r, 'max_image_regret') for r in rows if int(r['contradicting_images']) == 0)
        print('%s not flagged: largest image regret median %.3f, quartiles %.3f / %.3f, max %.3f; above 0.2: %d' %
              (name, v[len(v) // 2], v[len(v) // 4], v[3 * len(v) // 4], v[-1], sum(x > 0.2 for x in v)))
print('odd pairs: %d safe corners, %d within 3 cm of the first image\'s drape' %
      (sum(int(r['safe_corners']) for r in odd), sum(int(r['safe_within_3cm']) for r in odd)))
