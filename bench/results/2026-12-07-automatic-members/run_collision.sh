#!/usr/bin/env bash
# After run.sh (same $WORK): the benchmark's two self-collision variants at seed 61, made and recognised against
# both databases, then the whole seven-variant benchmark at seed 61 summarised. About 65 min on the 2-core machine (the 8 held-out drapes took 3 822 s).
set -u
D=.build/ws/devel/lib/textile_handling
OUT=bench/results/2026-12-07-automatic-members
PREV=bench/results/2026-12-07-coarse-grid-members
WORK=${WORK:-/tmp/am}
export OMP_WAIT_POLICY=passive OMP_NUM_THREADS=1
COLLISION_VARIANTS=choi_ko_collision,fine_collision
mkdir -p "$WORK/s61c"
$D/foreign_drape_bench --database "$WORK/none.sqlite" --out "$WORK/s61c" --holds 4 --views 3 --seed 61 --workers 2 \
  --variants $COLLISION_VARIANTS --max-time 20 > "$OUT/heldout_s61_collision.log" 2>&1
recognise() {  # DATABASE
  local v=$1 dir="$WORK/s61c_$1"
  mkdir -p "$dir"
  cp "$WORK/s61c/foreign_drapes.sqlite" "$dir/"
  $D/foreign_drape_bench --database "$WORK/$v.sqlite" --out "$dir" --holds 4 --views 3 --seed 61 \
    --variants $COLLISION_VARIANTS --workers 1 --max-time 20 > "$OUT/recognition_seed61_collision_$v.log" 2>&1
  cp "$dir/foreign_drapes.csv" "$OUT/recognition_seed61_collision_$v.csv"
  cp "$dir/foreign_corners.csv" "$OUT/recognition_seed61_collision_${v}_corners.csv"
}
recognise d067 & recognise auto & wait
python3 $PREV/summarise.py $OUT/recognition_seed61_collision_d067.csv auto=$OUT/recognition_seed61_collision_auto.csv \
  > $OUT/summary_seed61_collision.csv
for v in d067 auto; do
  (cat $OUT/recognition_seed61_$v.csv; tail -n +2 $OUT/recognition_seed61_collision_$v.csv) > "$WORK/seed61_all_$v.csv"
done
python3 $PREV/summarise.py "$WORK/seed61_all_d067.csv" auto="$WORK/seed61_all_auto.csv" > $OUT/summary_seed61_all_variants.csv
python3 $OUT/safe_corners.py $OUT/recognition_seed61_collision_d067_corners.csv \
  auto=$OUT/recognition_seed61_collision_auto_corners.csv > $OUT/safe_corners_seed61_collision.csv
