#!/usr/bin/env python3
"""Recomputes graspPointUncertainty (include/textile_handling/recognition/grasp_point_trust.h, with the tip
roughness term) from the corner rows, checks it against the recorded safe flags, and prints per set and
number of images: results, results with a safe corner, safe corners, safe corners within 3 cm; first for the
defaults, then for a grid of constants ranked on the calibration set (seed 11) at >= 95 % precision.
Usage (in this directory): tune_trust.py [CAL CHECK ...]; default seed11 seed1 thesis_seed1 seed31."""
import csv, itertools, sys

import importlib.util, os

# load(), bound() and evaluate() build on those of ../2026-12-05-multi-view-trust/tune_trust.py, with this rule's bound.
_spec = importlib.util.spec_from_file_location(
    'multi_view_trust', os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '2026-12-05-multi-view-trust', 'tune_trust.py'))
_previous = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_previous)
F, load = _previous.F, _previous.load
def bound(r, p):
    """The previous rule's bound (agreeing images take 0.5 cm off) plus the roughness term."""
    return _previous.bound(r, dict(p, agreeing_m=.005), lambda row, q: q['rough'] * max(0, F(row, 'tip_roughness_m')))


def evaluate(groups, p, views):
    return _previous.evaluate(groups, p, views, bound)


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
