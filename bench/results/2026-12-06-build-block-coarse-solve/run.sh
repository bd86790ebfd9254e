#!/bin/bash
# One towel simulation (hold point (0, 0.46) m, d = 2/3 cm, one thread) by the drape_db of the revision
# before the block LDL^T coarse solve and by this one, side by side (one per core), in rounds: with the
# builder's default solves and with the replay database's --cg-tolerance 0.001 --cg-warm-start.
#   OLD=<drape_db of e93f88a> NEW=<drape_db of this revision> bash run.sh [ROUNDS]
set -eu
here=$(cd "$(dirname "$0")" && pwd)
rounds=${1:-3}
export OMP_WAIT_POLICY=passive OMP_NUM_THREADS=1
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
echo "round,arm,solves,wall_s" > "$here/build_times.csv"
one() {  # arm binary solves-label round extra-args...
  local arm=$1 bin=$2 label=$3 r=$4; shift 4
  local db="$work/$arm-$label-$r.sqlite" t0 t1
  t0=$(date +%s.%N)
  "$bin" build --db "$db" --textile towel --hold 0,0.46 --spacing 0.006666666666666667 --threads 1 --quiet "$@" \
    > "$here/$arm-$label-$r.txt" 2>&1
  t1=$(date +%s.%N)
  echo "$r,$arm,$label,$(echo "$t1 - $t0" | bc)" >> "$here/build_times.csv"
}
for r in $(seq 1 "$rounds"); do
  for label in default fast; do
    extra=(); [ "$label" = fast ] && extra=(--cg-tolerance 0.001 --cg-warm-start)
    one old "$OLD" "$label" "$r" "${extra[@]}" &
    one new "$NEW" "$label" "$r" "${extra[@]}" &
    wait
  done
done
python3 "$here/summarise.py" "$here" | tee "$here/summary.txt"
