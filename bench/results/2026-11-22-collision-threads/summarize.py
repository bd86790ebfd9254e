#!/usr/bin/env python3
"""Median / range of collision, assembly and their ratio per build, from ab.sh output (stdin or file)."""
import statistics as st
import sys

runs = {}
for line in (open(sys.argv[1]) if len(sys.argv) > 1 else sys.stdin):
    f = line.split()
    if len(f) < 4 or 'coll' not in f:
        continue
    runs.setdefault(f[0], []).append((float(f[f.index('coll') + 1]), float(f[f.index('asm') + 1]), float(f[-1])))
for name, v in runs.items():
    c, a, r = zip(*v)
    print(f"{name:8s} n={len(v)} collision median {st.median(c):.3f} (min {min(c):.3f}) assembly median {st.median(a):.3f} "
          f"ratio median {st.median(r):.3f} [{min(r):.3f}, {max(r):.3f}]")
