#!/bin/bash
# Cost per step of the yarn sheet before and after the block LDL^T coarse solve and the fixed-size
# block-Jacobi (commits 95e133f and 1a8c14b), two yarn_step_bench binaries interleaved in one session.
#   OLD=<yarn_step_bench of e93f88a> NEW=<yarn_step_bench of this revision> bash run.sh [ROUNDS]
# The old binary comes from a worktree of e93f88a with its own catkin workspace (README.md).
set -eu
here=$(cd "$(dirname "$0")" && pwd)
rounds=${1:-3}
export OMP_WAIT_POLICY=passive
# The old binary has no "--stable-side 0"; a 2 x 2 sheet for one 1 ms step stands in for the skipped scan.
common=(--steps 5 --repeats 1 --linear-tolerance 1e-2 --reference-tolerance 0 --stable-side 2 --stable-time 0.001 --stable-dts 0.001)
for r in $(seq 1 "$rounds"); do
  # Alternate which binary goes first.
  if [ $((r % 2)) -eq 1 ]; then order="old new"; else order="new old"; fi
  mkdir -p "$here/semi_implicit" "$here/newton"
  for arm in $order; do
    bin=$OLD; [ "$arm" = new ] && bin=$NEW
    "$bin" --out "$here/semi_implicit/$arm-$r" --sides 128,250 "${common[@]}" > "$here/semi_implicit/$arm-$r.txt"
    "$bin" --out "$here/newton/$arm-$r" --sides 250 --integrator backward_euler_newton "${common[@]}" > "$here/newton/$arm-$r.txt"
  done
done
python3 "$here/summarise.py" "$here" | tee "$here/summary.txt"
