#!/bin/bash
# Interleaved A/B timing of foreign_drape_bench with one build and two databases: A = DB_A (the replay
# database, 6 x 6 quadrant hold points), B = DB_B (11 x 11); the pairs run one after the other, each on
# the choi_ko and stiff_light drapes of seed 1 (24 recognitions of one image and 24 of two).
# Usage: BIN=.../foreign_drape_bench DB_A=... DB_B=... HELD_OUT=.../foreign_drapes.sqlite OUT=DIR \
#        [PAIRS="1 2 3"] bash interleave_db.sh; then PAIRS=123 python3 ../2026-12-05-depth-only-render/summarize.py in OUT
set -euo pipefail
for k in ${PAIRS:-1 2 3}; do
  for v in A B; do
    D=$OUT/$v$k; mkdir -p "$D"; cp "$HELD_OUT" "$D/"
    DB=$DB_A; [ $v = B ] && DB=$DB_B
    OMP_WAIT_POLICY=passive OMP_NUM_THREADS=1 "$BIN" --database "$DB" --out "$D" --holds 4 --views 3 --seed 1 \
      --workers 1 --max-time 20 --variants choi_ko,stiff_light > "$D/run.log" 2>&1
  done
done
