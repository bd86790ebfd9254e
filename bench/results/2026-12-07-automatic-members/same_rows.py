#!/usr/bin/env python3
"""Usage: same_rows.py A.csv B.csv — whether two foreign_drape_bench CSVs hold the same results, timing columns
(*_ms) aside. Prints 'same rows (N)' or the first differing row and column."""
import csv
import sys


def rows(path):
    with open(path) as f:
        return [{k: v for k, v in r.items() if not k.endswith("_ms")} for r in csv.DictReader(f)]


a, b = rows(sys.argv[1]), rows(sys.argv[2])
if len(a) != len(b):
    print(f"different: {len(a)} rows against {len(b)}")
    sys.exit(1)
for i, (ra, rb) in enumerate(zip(a, b)):
    for k in ra:
        if ra[k] != rb.get(k):
            print(f"different: row {i + 2} column {k}: {ra[k]} against {rb.get(k)}")
            sys.exit(1)
print(f"same rows ({len(a)})")
