#!/bin/bash
# Interleaved A/B timing of foreign_drape_bench: A and B are two builds of the package (A: commit e231be7,
# B: commit a5eb8d3, the reach), pairs run one after the other (1-3, then 4-5: set the loop to "for k in 4 5").
# Usage: A=.../foreign_drape_bench B=.../foreign_drape_bench DB=towel_test.sqlite \
#        HELD_OUT=.../foreign_drapes.sqlite OUT=DIR bash interleave.sh
set -euo pipefail
for k in 1 2 3; do
  for v in A B; do
    D=$OUT/$v$k; mkdir -p "$D"; cp "$HELD_OUT" "$D/"
    BIN=$A; [ $v = B ] && BIN=$B
    OMP_WAIT_POLICY=passive OMP_NUM_THREADS=1 "$BIN" --database "$DB" --out "$D" --holds 4 --views 3 --seed 1 \
      --workers 1 --max-time 20 --variants choi_ko,stiff_light > "$D/run.log" 2>&1
  done
done
