#!/bin/bash
# Cost per step of the yarn sheet before and after the A P residual in the two-level preconditioner's
# V-cycle, two yarn_step_bench binaries interleaved in one session.
#   OLD=<yarn_step_bench of 522e7a4> NEW=<yarn_step_bench of this revision> bash run.sh [ROUNDS]
# Each binary is run from a copy of its own build's libraries (README.md).
set -eu
here=$(cd "$(dirname "$0")" && pwd)
rounds=${1:-3}
export OMP_WAIT_POLICY=passive
common=(--steps 5 --repeats 1 --linear-tolerance 1e-2 --reference-tolerance 0 --stable-side 0)
for r in $(seq 1 "$rounds"); do
  # Alternate which binary goes first.
  if [ $((r % 2)) -eq 1 ]; then order="old new"; else order="new old"; fi
  mkdir -p "$here/semi_implicit" "$here/newton"
  for arm in $order; do
    bin=$OLD; [ "$arm" = new ] && bin=$NEW
    LD_LIBRARY_PATH=$(dirname "$bin") "$bin" --out "$here/semi_implicit/$arm-$r" --sides 250 "${common[@]}" > "$here/semi_implicit/$arm-$r.txt"
    LD_LIBRARY_PATH=$(dirname "$bin") "$bin" --out "$here/newton/$arm-$r" --sides 250 --integrator backward_euler_newton "${common[@]}" > "$here/newton/$arm-$r.txt"
  done
done
python3 "$here/../2026-12-06-yarn-block-coarse-solve/summarise.py" "$here" | tee "$here/summary.txt"
