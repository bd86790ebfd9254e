#!/usr/bin/env python3
"""Where the two-image "a corner safe" gap between two databases comes from, on the same recognitions.

Usage: safe_corner_gap.py REF_PREFIX OTHER_PREFIX SEED [SEED ...]
  PREFIX is a path prefix such that PREFIX<seed>_<name>.csv is a foreign_drape_bench rows file and
  ..._<name>_corners.csv its per-corner rows, e.g. .../recognition_seed:d067. Rows of both databases come from the
  same held-out set, in the same order, four corners per recognition.
Prints key,reference,other lines: located corners (from an outline corner or the lowest point), how many lie within
3 cm, how many are safe; located in both; the unsafe located corners with a label margin below trust.label_margin_m
(0.04 m); recognitions with a safe corner in only one database, split by which result flagged contradicting images.
"""
import csv
import sys

DATA = ("outline_corner", "lowest_point")
LABEL_MARGIN_M = 0.04


def load(prefix, seeds, suffix):
    head, name = prefix.split(":")
    rows = []
    for s in seeds:
        rows += list(csv.DictReader(open(f"{head}{s}_{name}{suffix}.csv")))
    return rows


def two_images(corners):
    return [c for c in corners if c["views"] == "2"]


def main():
    ref, other, seeds = sys.argv[1], sys.argv[2], sys.argv[3:]
    ra, rb = load(ref, seeds, ""), load(other, seeds, "")
    ca, cb = load(ref, seeds, "_corners"), load(other, seeds, "_corners")
    if len(ra) != len(rb) or len(ca) != 4 * len(ra) or len(cb) != 4 * len(rb):
        sys.exit("rows do not pair: need the same recognitions, four corners each")
    out = []
    for cs, tag in ((ca, "reference"), (cb, "other")):
        loc = [c for c in two_images(cs) if c["evidence"] in DATA]
        out.append((tag, "located_corners", len(loc)))
        out.append((tag, "located_within_3cm", sum(float(c["error_m"]) < 0.03 for c in loc)))
        out.append((tag, "located_safe", sum(c["safe"] == "1" for c in loc)))
        out.append((tag, "located_safe_within_3cm", sum(c["safe"] == "1" and float(c["error_m"]) < 0.03 for c in loc)))
        out.append((tag, "unsafe_located_label_margin_below_4cm",
                    sum(c["safe"] != "1" and float(c["label_margin_m"]) < LABEL_MARGIN_M for c in loc)))
    both = [(x, y) for x, y in zip(ca, cb) if x["views"] == "2" and x["evidence"] in DATA and y["evidence"] in DATA]
    out.append(("both", "located_in_both", len(both)))
    out.append(("reference", "safe_of_located_in_both", sum(x["safe"] == "1" for x, _ in both)))
    out.append(("other", "safe_of_located_in_both", sum(y["safe"] == "1" for _, y in both)))
    split = {}
    for i, (x, y) in enumerate(zip(ra, rb)):
        if x["views"] != "2":
            continue
        sa = any(c["safe"] == "1" for c in ca[4 * i:4 * i + 4])
        sb = any(c["safe"] == "1" for c in cb[4 * i:4 * i + 4])
        if sa == sb:
            continue
        ka, kb = int(x["contradicting_images"]) > 0, int(y["contradicting_images"]) > 0
        who = "reference" if sa else "other"
        flag = {(False, False): "neither", (True, True): "both"}.get((ka, kb), "reference" if ka else "other")
        key = f"safe_corner_only_in_{who}_contradiction_flag_in_{flag}"
        split[key] = split.get(key, 0) + 1
    for k in sorted(split):
        out.append(("count", k, split[k]))
    print("side,figure,value")
    for side, k, v in out:
        print(f"{side},{k},{v}")


if __name__ == "__main__":
    main()
