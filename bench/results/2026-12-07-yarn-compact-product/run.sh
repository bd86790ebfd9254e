#!/bin/bash
# Cost per step of the 62.5k yarn sheet before (a2ce2fd) and after (b9ee7da) the solvers' compact copy
# of the system and the crossing pass's single angle evaluation (README.md): two yarn_step_bench
# binaries alternating in one session, semi_implicit and backward_euler_newton, 1 and 2 threads each.
#   OLD=<yarn_step_bench of a2ce2fd> NEW=<yarn_step_bench of b9ee7da> bash run.sh [ROUNDS] [FIRST] [WHICH]
# ROUNDS rounds numbered from FIRST (default 1); WHICH = both (default) or semi_implicit.
set -eu
here=${OUT_DIR:-$(cd "$(dirname "$0")" && pwd)}  # OUT_DIR: another results directory reusing this script
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
python3 "$(dirname "$0")/../2026-12-06-yarn-block-coarse-solve/summarise.py" "$here" | tee "$here/summary.txt"
