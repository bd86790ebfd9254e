#!/usr/bin/env python3
"""Usage: safe_by_evidence.py NAME=corners.csv[,corners.csv..] ... — two-image corners per evidence kind (where the
recognizer located each corner from), and how many of them were reported safe."""
import collections
import csv
import sys

print("database,evidence,corners,safe")
for arg in sys.argv[1:]:
    name, paths = arg.split("=", 1)
    rows = [r for p in paths.split(",") for r in csv.DictReader(open(p)) if r["views"] == "2"]
    kinds = collections.Counter(r["evidence"] for r in rows)
    safe = collections.Counter(r["evidence"] for r in rows if r["safe"] == "1")
    for k in sorted(kinds):
        print(f"{name},{k},{kinds[k]},{safe[k]}")
