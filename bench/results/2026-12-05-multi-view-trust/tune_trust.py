#!/usr/bin/env python3
"""Recomputes graspPointUncertainty (include/textile_handling/recognition/grasp_point_trust.h) from the corner
rows and reports, per number of images, (results, results with a safe corner, safe corners, safe corners
within 3 cm) for the defaults and for a grid of constants ranked on the calibration seed (11), each with
the check seed (1). Usage: tune_trust.py (run in this directory)."""
import csv, itertools

F = lambda r, k: float(r[k])


def load(d):
    rows = list(csv.DictReader(open(d + '/foreign_corners.csv')))
    res = list(csv.DictReader(open(d + '/foreign_drapes.csv')))
    groups = [rows[i:i + 4] for i in range(0, len(rows), 4)]  # 4 corners per result, in result order
    assert len(groups) == len(res)
    for g, r in zip(groups, res):
        for q in g:
            q['contra'] = int(r['contradicting_images'])
    return groups


BASE = {'model': .15, 'surface': .12, 'outline_corner': .025, 'lowest_point': .02}


def bound(r, p, extra=None):
    """The rule's bound for corner row r under constants p; `extra(r, p)` adds a term for located points
    before the doubling (../2026-12-05-tip-roughness/tune_trust.py: the tip roughness)."""
    ev = r['evidence']
    u = p['lp'] if ev == 'lowest_point' else BASE[ev]
    located = ev in ('outline_corner', 'lowest_point')
    agreeing = located and int(r['located_images']) >= 2
    if located:
        shift, margin = max(0, F(r, 'located_shift_m')), F(r, 'label_margin_m')
        if agreeing:
            u = max(0, u - p['agreeing_m'])
        u += p['gain'] * shift
        if margin < p['margin']:
            u += shift + max(0, margin)
        u += max(0, F(r, 'disagreement_m'))
        if extra:
            u += extra(r, p)
    score = 0 if r['contra'] > 0 and not agreeing else F(r, 'score')
    if score < (p['weak_agreeing'] if agreeing else p['weak']):
        u *= 2
    return u


def evaluate(groups, p, views, bound_fn=None):
    """(results, results with a safe corner, safe corners, safe corners within 3 cm) for `views` images;
    `bound_fn(row, p)` replaces this rule's bound (../2026-12-05-tip-roughness/tune_trust.py)."""
    b = bound_fn or bound
    g = [x for x in groups if x[0]['views'] == views]
    safe = [r for x in g for r in x if b(r, p) <= .03]
    return len(g), sum(any(b(r, p) <= .03 for r in x) for x in g), len(safe), sum(F(r, 'error_m') <= .03 for r in safe)


def main():
    cal, check = load('after_seed11'), load('after_seed1')
    defaults = dict(lp=.02, agreeing_m=.005, gain=.5, margin=.05, weak=.75, weak_agreeing=.65)
    recorded = sum((bound(r, defaults) <= .03) != (r['safe'] == '1') for g in cal + check for r in g)
    print('defaults: seed 11', evaluate(cal, defaults, '1'), evaluate(cal, defaults, '2'),
          'seed 1', evaluate(check, defaults, '1'), evaluate(check, defaults, '2'),
          '(rows whose recorded safe flag differs: %d)' % recorded)
    ranked = []
    for lp, ag, gain, margin, weak, wa in itertools.product([.015, .02, .025], [0, .005, .01], [.25, .5, 1], [.03, .05, .07],
                                                            [.7, .75, .8], [.6, .65, .7, .75]):
        p = dict(lp=lp, agreeing_m=ag, gain=gain, margin=margin, weak=weak, weak_agreeing=wa)
        one, two = evaluate(cal, p, '1'), evaluate(cal, p, '2')
        precision = (one[3] + two[3]) / max(1, one[2] + two[2])
        ranked.append((precision >= 0.95, min(one[1] / one[0], two[1] / two[0]), precision, p, one, two))
    ranked.sort(key=lambda x: (x[0], x[1], x[2]), reverse=True)
    for ok, cover, precision, p, one, two in ranked[:10]:
        print('%.3f %.3f %s seed 11 %s %s seed 1 %s %s' % (cover, precision, p, one, two, evaluate(check, p, '1'), evaluate(check, p, '2')))


if __name__ == '__main__':
    main()
