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
# The stored rest shapes of each build, as a digest (equal digests: the same shapes bit for bit). The last two lines
# of shapes_digest.txt are the databases of ../2026-12-07-automatic-members (its $WORK, /tmp/am), added by hand with
# the same script.
python3 "$OUT/shapes_digest.py" "$WORK"/auto_{1,2,3}.sqlite "$WORK"/d067_{1,2,3}.sqlite > "$OUT/shapes_digest.txt"
