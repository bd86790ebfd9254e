#!/usr/bin/env bash
# Reproduces this directory: the towel's thesis grid built with `drape_db build --auto` beside today's
# d = 2/3 cm build, the two compared hold point by hold point, and the recognition benchmark on drapes the
# database did not make against the d = 2/3 cm database and against a d = 1 cm database (the coarser
# candidate the automatic search rejected). Run from the repository root after setup.sh; about 1.5 h on
# the 2-core machine. Scratch files (databases, held-out drapes) go to $WORK (default /tmp/automatic-build).
set -u
D=.build/ws/devel/lib/textile_handling
OUT=bench/results/2026-12-06-automatic-build
WORK=${WORK:-/tmp/automatic-build}
mkdir -p "$WORK/d067" "$WORK/d1"
export OMP_WAIT_POLICY=passive OMP_NUM_THREADS=1
COMMON="--textile towel --grid 6x6 --cg-tolerance 0.001 --cg-warm-start --threads 1 --sim-threads 1"
# The two builds side by side, one thread each.
$D/drape_db build --db "$WORK/d067.sqlite" --spacing 0.006666666666666667 $COMMON > "$OUT/build_d067.log" 2>&1 &
$D/drape_db build --db "$WORK/auto.sqlite" --auto $COMMON > "$OUT/build_auto.log" 2>&1 &
wait
python3 "$OUT/compare_builds.py" "$WORK/d067.sqlite" "$WORK/auto.sqlite" > "$OUT/compare_d067_auto.csv"
# The coarser candidate, for the recognition comparison.
$D/drape_db build --db "$WORK/d1.sqlite" --spacing 0.01 $COMMON > "$OUT/build_d1.log" 2>&1
# Held-out drapes once (foreign_drape_bench builds or resumes them in its --out directory), then both
# databases recognise the same renders.
$D/foreign_drape_bench --database "$WORK/d067.sqlite" --out "$WORK/d067" --holds 4 --views 3 --workers 1 --max-time 20 \
  > "$OUT/recognition_d067.log" 2>&1
cp "$WORK/d067/foreign_drapes.sqlite" "$WORK/d1/"
$D/foreign_drape_bench --database "$WORK/d1.sqlite" --out "$WORK/d1" --holds 4 --views 3 --workers 1 --max-time 20 \
  > "$OUT/recognition_d1.log" 2>&1
for v in d067 d1; do
  cp "$WORK/$v/foreign_drapes.csv" "$OUT/recognition_${v}.csv"
  cp "$WORK/$v/foreign_corners.csv" "$OUT/recognition_${v}_corners.csv"
done
