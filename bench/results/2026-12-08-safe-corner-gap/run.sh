#!/usr/bin/env bash
# Reproduces this directory from the rows of ../2026-12-07-automatic-members (seeds 61 and 71, the pre-registered
# fresh sets): where the automatic database's lower two-image "a corner safe" share comes from. Seconds.
set -u
OUT=bench/results/2026-12-08-safe-corner-gap
AM=bench/results/2026-12-07-automatic-members/recognition_seed
python3 $OUT/safe_corner_gap.py "$AM:d067" "$AM:auto" 61 71 > $OUT/safe_corner_gap_seeds61_71.csv
