#!/usr/bin/env python3
"""Largest particle distance between the rest shapes of two databases of the same textile, hold point by hold
point, after the best turn of the second about the vertical axis through its hold (the highest particle),
searched in 1-degree steps; a hanging drape's turn about that axis does not matter to recognition, which
stores views all round. Usage: aligned_distance.py A.sqlite B.sqlite > aligned.csv"""
import math
import sqlite3
import struct
import sys


def shapes(path):
    con = sqlite3.connect(f"file:{path}?mode=ro", uri=True)
    out = {}
    for key, blob in con.execute("SELECT hold_key, positions FROM simulations WHERE source = 'identity' AND status = 'done'"):
        blob = bytes(blob)
        n = struct.unpack_from("<Q", blob, 8)[0]
        xyz = struct.unpack_from("<%dd" % (3 * n), blob, 16)
        out[key] = [xyz[3 * k:3 * k + 3] for k in range(n)]
    return out


a, b = shapes(sys.argv[1]), shapes(sys.argv[2])
print("hold_key,max_particle_distance_m,aligned_max_particle_distance_m,turn_deg")
for key in sorted(set(a) & set(b)):
    pa, pb = a[key], b[key]
    if len(pa) != len(pb):
        continue
    raw = max(math.dist(p, q) for p, q in zip(pa, pb))
    ha = max(pa, key=lambda p: p[2])
    hb = max(pb, key=lambda p: p[2])
    best = (float("inf"), 0)
    for deg in range(360):
        c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
        d = 0.0
        for p, q in zip(pa, pb):
            x, y = q[0] - hb[0], q[1] - hb[1]
            r = (ha[0] + c * x - s * y, ha[1] + s * x + c * y, q[2])
            d = max(d, math.dist(p, r))
            if d >= best[0]:
                break
        if d < best[0]:
            best = (d, deg)
    print("%s,%.6g,%.6g,%d" % (str(key).replace(",", " "), raw, best[0], best[1]))
