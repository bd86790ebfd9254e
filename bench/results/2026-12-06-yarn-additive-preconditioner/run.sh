#!/bin/bash
# Interleaved: smoothing 1 (the default V-cycle) and 0 (additive two-level), 3 rounds each.
set -e
REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/../../.." && pwd)"
BIN="$REPO/.build/ws/devel/lib/textile_handling/yarn_step_bench"
export OMP_WAIT_POLICY=passive
OUT=${1:?usage: run.sh OUT_DIR}
for r in 1 2 3; do
  for s in 1 0; do
    if [ $((r % 2)) = 0 ]; then s=$((1 - s)); fi
    $BIN --out $OUT/r${r}_s${s} --sides 128,250 --steps 5 --repeats 1 --linear-tolerance 1e-2 \
      --reference-tolerance 0 --stable-dts 0.001 --stable-time 0.002 --smoothing-steps $s > $OUT/r${r}_s${s}.txt 2>&1
  done
done
