#!/bin/bash
# Interleaved comparison of two speed_accuracy_bench binaries (before/after a change), 1 and 2 threads.
# usage: run.sh BEFORE_BINARY AFTER_BINARY OUT_DIR [ROUNDS]
# Writes OUT_DIR/runs.csv (trial = interleaved round, threads, binary, then the bench's own runs.csv row).
set -euo pipefail
before=$1; after=$2; out=$3; rounds=${4:-3}
export OMP_WAIT_POLICY=passive
mkdir -p "$out"
first=1
for r in $(seq 1 "$rounds"); do
  for t in 1 2; do
    for b in before after; do
      bin=$before; [ "$b" = after ] && bin=$after
      d="$out/r${r}_t${t}_$b"
      "$bin" --out "$d" --scenes square_corner --models particle_kes,choi_ko \
        --integrators semi_implicit,backward_euler_newton --spacings 0.03,0.015 --reference-spacing 0.04 \
        --repeats 1 --threads "$t" > "$d.log" 2>&1
      if [ $first = 1 ]; then echo "trial,threads,binary,$(head -1 "$d/runs.csv")" > "$out/runs.csv"; first=0; fi
      tail -n +2 "$d/runs.csv" | sed "s/^/$r,$t,$b,/" >> "$out/runs.csv"
    done
  done
done
echo "wrote $out/runs.csv"
