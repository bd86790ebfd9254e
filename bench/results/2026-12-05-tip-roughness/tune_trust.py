#!/usr/bin/env python3
"""Recomputes graspPointUncertainty (include/textile_handling/recognition/grasp_point_trust.h, with the tip
roughness term) from the corner rows, checks it against the recorded safe flags, and prints per set and
number of images: results, results with a safe corner, safe corners, safe corners within 3 cm; first for the
defaults, then for a grid of constants ranked on the calibration set (seed 11) at >= 95 % precision.
Usage (in this directory): tune_trust.py [CAL CHECK ...]; default seed11 seed1 thesis_seed1 seed31."""
import csv, itertools, sys

F = lambda r, k: float(r[k])
BASE = {'model': .15, 'surface': .12, 'outline_corner': .025, 'lowest_point': .02}


def load(d):
    rows = list(csv.DictReader(open(d + '/foreign_corners.csv')))
    res = list(csv.DictReader(open(d + '/foreign_drapes.csv')))
    groups = [rows[i:i + 4] for i in range(0, len(rows), 4)]  # 4 corners per result, in result order
    assert len(groups) == len(res)
    for g, r in zip(groups, res):
        for q in g:
            q['contra'] = int(r['contradicting_images'])
    return groups


def bound(r, p):
    ev = r['evidence']
    u = p['lp'] if ev == 'lowest_point' else BASE[ev]
    located = ev in ('outline_corner', 'lowest_point')
    agreeing = located and int(r['located_images']) >= 2
    if located:
        shift, margin = max(0, F(r, 'located_shift_m')), F(r, 'label_margin_m')
        if agreeing:
            u = max(0, u - .005)
        u += p['gain'] * shift
        if margin < p['margin']:
            u += shift + max(0, margin)
        u += max(0, F(r, 'disagreement_m'))
        u += p['rough'] * max(0, F(r, 'tip_roughness_m'))
    score = 0 if r['contra'] > 0 and not agreeing else F(r, 'score')
    if score < (p['weak_agreeing'] if agreeing else p['weak']):
        u *= 2
    return u


def evaluate(groups, p, views):
    g = [x for x in groups if x[0]['views'] == views]
    safe = [r for x in g for r in x if bound(r, p) <= .03]
    return len(g), sum(any(bound(r, p) <= .03 for r in x) for x in g), len(safe), sum(F(r, 'error_m') <= .03 for r in safe)


def show(name, groups, p):
    return ' '.join('%s/%s img: %d/%d results safe, %d/%d within 3 cm' % ((name, v) + tuple(evaluate(groups, p, v)[i] for i in (1, 0, 3, 2)))
                    for v in '12')


names = sys.argv[1:] or ['seed11', 'seed1', 'thesis_seed1', 'seed31']
sets = {n: load(n) for n in names}
defaults = dict(lp=.02, gain=.25, margin=.04, weak=.6, weak_agreeing=.6, rough=10)
differ = sum((bound(r, defaults) <= .03) != (r['safe'] == '1') for g in sets.values() for x in g for r in x)
print('defaults (rows whose recorded safe flag differs: %d)' % differ)
for n in names:
    print('  ' + show(n, sets[n], defaults))
cal = sets[names[0]]
ranked = []
for lp, gain, margin, weak, rough in itertools.product([.015, .02, .025], [.25, .5, 1], [.03, .04, .05], [.6, .65, .7, .75],
                                                       [0, 5, 10, 15, 20]):
    p = dict(lp=lp, gain=gain, margin=margin, weak=weak, weak_agreeing=min(weak, .6), rough=rough)
    one, two = evaluate(cal, p, '1'), evaluate(cal, p, '2')
    precision = (one[3] + two[3]) / max(1, one[2] + two[2])
    ranked.append((precision >= 0.95, min(one[1] / one[0], two[1] / two[0]), precision, p))
ranked.sort(key=lambda x: (x[0], x[1], x[2]), reverse=True)
print('best on %s at >= 95 %% precision (coverage = the lesser of one and two images):' % names[0])
for ok, cover, precision, p in ranked[:5]:
    print('  %.2f %.3f %s' % (cover, precision, p))
    for n in names[1:]:
        print('      ' + show(n, sets[n], p))
best_without = max((x for x in ranked if x[3]['rough'] == 0), key=lambda x: (x[0], x[1], x[2]))
print('best without the roughness term: %.2f %.3f %s' % (best_without[1], best_without[2], best_without[3]))
for n in names[1:]:
    print('      ' + show(n, sets[n], best_without[3]))
