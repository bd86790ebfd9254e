#!/usr/bin/env bash
# Reproduces this directory: three pairs of whole towel database builds (thesis 6 x 6 quadrant grid), in each pair
# `drape_db build --auto` (defaults, members rule on) beside `--spacing 0.006666666666666667`, one thread each and
# each pinned to its own core (the cores swap between pairs). Run from the repository root after scripts/setup.sh.
# About 65 min on the 2-core machine. Scratch databases go to $WORK.
set -u
D=.build/ws/devel/lib/textile_handling
OUT=bench/results/2026-12-08-automatic-build-cost
WORK=${WORK:-/tmp/abc}
export OMP_WAIT_POLICY=passive OMP_NUM_THREADS=1
mkdir -p "$WORK"
COMMON="--textile towel --grid 6x6 --cg-tolerance 0.001 --cg-warm-start --threads 1 --sim-threads 1"
echo "pair,build,core,wall_s,user_s,system_s,max_rss_kb" > "$OUT/times.csv"
build() {  # PAIR NAME CORE ARGS...: one build into a new database; appends its /usr/bin/time figures to times.csv
  local pair=$1 name=$2 core=$3; shift 3
  rm -f "$WORK/${name}_$pair.sqlite"*
  taskset -c "$core" /usr/bin/time -f "$pair,$name,$core,%e,%U,%S,%M" -o "$WORK/time_${name}_$pair" \
    $D/drape_db build --db "$WORK/${name}_$pair.sqlite" "$@" $COMMON > "$OUT/build_${name}_$pair.log" 2>&1
  cat "$WORK/time_${name}_$pair" >> "$OUT/times.csv"
}
for pair in 1 2 3; do
  if [ $((pair % 2)) = 1 ]; then ca=0; cd=1; else ca=1; cd=0; fi
  build $pair auto $ca --auto &
  build $pair d067 $cd --spacing 0.006666666666666667 --quiet &
  wait
done
python3 "$OUT/ratios.py" "$OUT/times.csv" > "$OUT/ratios.txt"
# Each build's stored rest shapes and views against pair 1's of the same kind, and against the database of that kind
# recognised in ../2026-12-07-automatic-members (its $WORK, $AM_WORK, default /tmp/am).
AM_WORK=${AM_WORK:-/tmp/am}
COMPARE=bench/results/2026-12-06-automatic-build/compare_builds.py
for v in auto d067; do
  for p in 2 3; do python3 $COMPARE "$WORK/${v}_1.sqlite" "$WORK/${v}_$p.sqlite" > "$OUT/compare_${v}_1_$p.csv"; done
  python3 $COMPARE "$WORK/${v}_1.sqlite" "$AM_WORK/$v.sqlite" > "$OUT/compare_${v}_1_recognised.csv"
done
