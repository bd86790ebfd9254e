#!/bin/bash
# Cost per step of the 62.5k yarn sheet before (679ff82) and after this revision's changes to the
# step (README.md): two yarn_step_bench binaries alternating in one session, semi_implicit and
# backward_euler_newton, 1 and 2 threads each.
#   OLD=<yarn_step_bench of 679ff82> NEW=<yarn_step_bench of this revision> bash run.sh [ROUNDS]
set -eu
here=$(cd "$(dirname "$0")" && pwd)
rounds=${1:-3}
export OMP_WAIT_POLICY=passive
common=(--sides 250 --steps 5 --repeats 1 --linear-tolerance 1e-2 --reference-tolerance 0 --stable-side 0)
mkdir -p "$here/semi_implicit" "$here/newton"
for r in $(seq 1 "$rounds"); do
  order="old new"; [ $((r % 2)) -eq 0 ] && order="new old"
  for arm in $order; do
    bin=$OLD; [ "$arm" = new ] && bin=$NEW
    export LD_LIBRARY_PATH; LD_LIBRARY_PATH=$(dirname "$bin")
    "$bin" --out "$here/semi_implicit/$arm-$r" "${common[@]}" > "$here/semi_implicit/$arm-$r.txt"
    "$bin" --out "$here/newton/$arm-$r" --integrator backward_euler_newton "${common[@]}" > "$here/newton/$arm-$r.txt"
  done
done
python3 "$here/../2026-12-06-yarn-block-coarse-solve/summarise.py" "$here" | tee "$here/summary.txt"
