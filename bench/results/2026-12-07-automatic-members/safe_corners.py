#!/usr/bin/env python3
"""Usage: safe_corners.py REF_corners.csv NAME=corners.csv ... — per database and number of images: the share of
results with at least one corner reported safe, the safe corners within 3 cm, and, paired result by result with
the reference (same held-out set, same order), the results with a safe corner only with the reference, only with
the database, and the exact two-sided sign-test p of that split. Four rows per result (foreign_corners.csv)."""
import csv
import sys
from math import comb


def results(path):
    with open(path) as f:
        rows = list(csv.DictReader(f))
    assert len(rows) % 4 == 0, path
    out = []
    for k in range(0, len(rows), 4):
        group = rows[k:k + 4]
        views = group[0]["views"]
        assert all(r["views"] == views for r in group), path
        safe = [float(r["error_m"]) for r in group if r["safe"] == "1"]
        out.append((group[0]["variant"], views, len(safe) > 0, len(safe), sum(e <= 0.03 for e in safe)))
    return out


def sign_p(a, b):
    n, k = a + b, min(a, b)
    return 1.0 if n == 0 else min(1.0, 2 * sum(comb(n, i) for i in range(k + 1)) / 2 ** n)


ref = results(sys.argv[1])
print("database,views,results,any_safe_share,reference_any_safe_share,safe_corners,safe_within_3cm,"
      "reference_safe_corners,reference_safe_within_3cm,only_reference,only_database,sign_test_p")
for arg in sys.argv[2:]:
    name, path = arg.split("=", 1)
    db = results(path)
    assert [r[:2] for r in db] == [r[:2] for r in ref], f"{path}: not the reference's results"
    for views in sorted({r[1] for r in ref}):
        pairs = [(a, b) for a, b in zip(ref, db) if a[1] == views]
        n = len(pairs)
        only_ref = sum(a[2] and not b[2] for a, b in pairs)
        only_db = sum(b[2] and not a[2] for a, b in pairs)
        print(f"{name},{views},{n},{sum(b[2] for _, b in pairs) / n:.3f},{sum(a[2] for a, _ in pairs) / n:.3f},"
              f"{sum(b[3] for _, b in pairs)},{sum(b[4] for _, b in pairs)},{sum(a[3] for a, _ in pairs)},"
              f"{sum(a[4] for a, _ in pairs)},{only_ref},{only_db},{sign_p(only_ref, only_db):.3f}")
