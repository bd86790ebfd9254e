#!/usr/bin/env bash
# Reproduces this directory: the towel's thesis grid built with `drape_db build --auto` (which now also chooses
# the step error tolerance) beside today's d = 2/3 cm build, the two compared hold point by hold point, and the
# recognition benchmark on drapes the database did not make against both. Run from the repository root after
# setup.sh; about 1.5 h on the 2-core machine. Scratch files (databases, held-out drapes) go to $WORK.
set -u
D=.build/ws/devel/lib/textile_handling
OUT=bench/results/2026-12-07-automatic-step-tolerance
WORK=${WORK:-/tmp/ab}
mkdir -p "$WORK/d067" "$WORK/auto"
export OMP_WAIT_POLICY=passive OMP_NUM_THREADS=1
COMMON="--textile towel --grid 6x6 --cg-tolerance 0.001 --cg-warm-start --threads 1 --sim-threads 1"
# Held-out drapes once (the recognition step of this first run has no database yet and stops).
$D/foreign_drape_bench --database "$WORK/none.sqlite" --out "$WORK/d067" --holds 4 --views 3 --workers 1 --max-time 20 \
  > "$OUT/heldout.log" 2>&1
cp "$WORK/d067/foreign_drapes.sqlite" "$WORK/auto/"
# The two builds side by side, one thread each.
$D/drape_db build --db "$WORK/d067.sqlite" --spacing 0.006666666666666667 $COMMON > "$OUT/build_d067.log" 2>&1 &
$D/drape_db build --db "$WORK/auto.sqlite" --auto --auto-step-factors 3 $COMMON > "$OUT/build_auto.log" 2>&1 &
wait
python3 $OUT/aligned_distance.py "$WORK/d067.sqlite" "$WORK/auto.sqlite" > "$OUT/aligned_d067_auto.csv"
python3 bench/results/2026-12-06-automatic-build/compare_builds.py "$WORK/d067.sqlite" "$WORK/auto.sqlite" \
  > "$OUT/compare_d067_auto.csv"
# Both databases recognise the same renders, side by side.
$D/foreign_drape_bench --database "$WORK/d067.sqlite" --out "$WORK/d067" --holds 4 --views 3 --workers 1 --max-time 20 \
  > "$OUT/recognition_d067.log" 2>&1 &
$D/foreign_drape_bench --database "$WORK/auto.sqlite" --out "$WORK/auto" --holds 4 --views 3 --workers 1 --max-time 20 \
  > "$OUT/recognition_auto.log" 2>&1 &
wait
for v in d067 auto; do
  cp "$WORK/$v/foreign_drapes.csv" "$OUT/recognition_${v}.csv"
  cp "$WORK/$v/foreign_corners.csv" "$OUT/recognition_${v}_corners.csv"
done
python3 "$OUT/paired.py" "$OUT/recognition_d067.csv" "$OUT/recognition_auto.csv" > "$OUT/paired_d067_auto.csv"
# The probe (four hold points, 0.1 / 0.3 / 1 mm alternating in one process): probe/probe.sh.
