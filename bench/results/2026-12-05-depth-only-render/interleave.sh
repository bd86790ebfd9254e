#!/bin/bash
# Interleaved A/B timing of foreign_drape_bench: A and B are two builds of the package (here A: the commit
# before the depth-only renders, B: the commit that adds them; ../2026-12-05-render-speed/ and
# ../2026-12-05-shape-fit-reach/ use it for other pairs of commits), the pairs run one after the other.
# Usage: A=.../foreign_drape_bench B=.../foreign_drape_bench DB=towel_test.sqlite \
#        HELD_OUT=.../foreign_drapes.sqlite OUT=DIR [PAIRS="1 2 3"] bash interleave.sh
# One build against two databases instead (../2026-12-05-hold-density/): A = B = that build, DB_A and
# DB_B the databases (each defaults to DB).
set -euo pipefail
for k in ${PAIRS:-1 2 3}; do
  for v in A B; do
    D=$OUT/$v$k; mkdir -p "$D"; cp "$HELD_OUT" "$D/"
    BIN=$A; [ $v = B ] && BIN=$B
    DBV=${DB_A:-$DB}; [ $v = B ] && DBV=${DB_B:-$DB}
    OMP_WAIT_POLICY=passive OMP_NUM_THREADS=1 "$BIN" --database "$DBV" --out "$D" --holds 4 --views 3 --seed 1 \
      --workers 1 --max-time 20 --variants choi_ko,stiff_light > "$D/run.log" 2>&1
  done
done
