#!/bin/bash
# Cost per step of the 62.5k yarn sheet before (a2ce2fd) and after (dff8f1a) the solvers' compact copy
# of the system, the single angle evaluation per crossing pair and the yarn model's remaining serial
# loops on all threads (README.md): two yarn_step_bench binaries alternating in one session.
#   OLD=<yarn_step_bench of a2ce2fd> NEW=<yarn_step_bench of dff8f1a> bash run.sh [ROUNDS] [FIRST] [WHICH]
# ROUNDS rounds numbered from FIRST (default 1); WHICH = both (default) or semi_implicit.
set -eu
here=$(cd "$(dirname "$0")" && pwd)
rounds=${1:-3}
first=${2:-1}
which=${3:-both}
export OMP_WAIT_POLICY=passive
common=(--sides 250 --steps 5 --repeats 1 --linear-tolerance 1e-2 --reference-tolerance 0 --stable-side 0)
mkdir -p "$here/semi_implicit" "$here/newton"
for r in $(seq "$first" $((first + rounds - 1))); do
  order="old new"; [ $((r % 2)) -eq 0 ] && order="new old"
  for arm in $order; do
    bin=$OLD; [ "$arm" = new ] && bin=$NEW
    export LD_LIBRARY_PATH; LD_LIBRARY_PATH=$(dirname "$bin")
    "$bin" --out "$here/semi_implicit/$arm-$r" "${common[@]}" > "$here/semi_implicit/$arm-$r.txt"
    [ "$which" = semi_implicit ] && continue
    "$bin" --out "$here/newton/$arm-$r" --integrator backward_euler_newton "${common[@]}" > "$here/newton/$arm-$r.txt"
  done
done
python3 "$here/../2026-12-06-yarn-block-coarse-solve/summarise.py" "$here" | tee "$here/summary.txt"
