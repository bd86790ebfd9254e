#!/usr/bin/env bash
# Reproduces this directory: the towel's thesis grid built with `drape_db build --auto` (members rule on, default
# options) beside the d = 2/3 cm build, one thread each, then both recognised on fresh held-out drapes (seeds 61
# and 71, new; seed 41 again as an identity check against ../2026-12-07-coarse-grid-members/). Run from the
# repository root after scripts/setup.sh. About 75 min on the 2-core machine. Scratch files go to $WORK.
set -u
D=.build/ws/devel/lib/textile_handling
OUT=bench/results/2026-12-07-automatic-members
PREV=bench/results/2026-12-07-coarse-grid-members
WORK=${WORK:-/tmp/am}
export OMP_WAIT_POLICY=passive OMP_NUM_THREADS=1
mkdir -p "$WORK"
: > "$OUT/times.txt"
COMMON="--textile towel --grid 6x6 --cg-tolerance 0.001 --cg-warm-start --threads 1 --sim-threads 1"
timed() {  # NAME COMMAND...: runs the command, appends "NAME seconds" to times.txt
  local name=$1 s; shift; s=$(date +%s.%N); "$@"; echo "$name $(echo "$(date +%s.%N) - $s" | bc)" >> "$OUT/times.txt"
}
# Side by side, one thread each. The automatic build prints its search (stderr, "auto:" lines) and its choice.
timed auto $D/drape_db build --db "$WORK/auto.sqlite" --auto $COMMON > "$OUT/auto_build.log" 2> "$WORK/auto_build.err" &
timed d067 $D/drape_db build --db "$WORK/d067.sqlite" --spacing 0.006666666666666667 $COMMON --quiet \
  > "$OUT/d067_build.log" 2>&1 &
wait
grep "^auto:" "$WORK/auto_build.err" > "$OUT/auto_search.log"
FRESH_VARIANTS=choi_ko,stiff_light,soft_heavy,heap,thesis
for seed in 61 71 41; do
  mkdir -p "$WORK/s$seed"
  $D/foreign_drape_bench --database "$WORK/none.sqlite" --out "$WORK/s$seed" --holds 4 --views 3 --seed $seed --workers 2 \
    --variants $FRESH_VARIANTS --max-time 20 > "$OUT/heldout_s$seed.log" 2>&1
done
recognise() {  # SEED DATABASE: the set's renders recognised against $WORK/DATABASE.sqlite
  local seed=$1 v=$2 dir="$WORK/s$1_$2"
  mkdir -p "$dir"
  cp "$WORK/s$seed/foreign_drapes.sqlite" "$dir/"
  $D/foreign_drape_bench --database "$WORK/$v.sqlite" --out "$dir" --holds 4 --views 3 --seed $seed \
    --variants $FRESH_VARIANTS --workers 1 --max-time 20 > "$OUT/recognition_seed${seed}_$v.log" 2>&1
  cp "$dir/foreign_drapes.csv" "$OUT/recognition_seed${seed}_$v.csv"
  cp "$dir/foreign_corners.csv" "$OUT/recognition_seed${seed}_${v}_corners.csv"
}
recognise 61 d067 & recognise 61 auto & wait
recognise 71 d067 & recognise 71 auto & wait
recognise 41 d067 & recognise 41 auto & wait
python3 $PREV/summarise.py $OUT/recognition_seed61_d067.csv auto=$OUT/recognition_seed61_auto.csv > $OUT/summary_seed61.csv
python3 $PREV/summarise.py $OUT/recognition_seed71_d067.csv auto=$OUT/recognition_seed71_auto.csv > $OUT/summary_seed71.csv
for v in d067 auto; do
  (cat $OUT/recognition_seed61_$v.csv; tail -n +2 $OUT/recognition_seed71_$v.csv) > "$WORK/new_fresh_$v.csv"
done
python3 $PREV/summarise.py "$WORK/new_fresh_d067.csv" auto="$WORK/new_fresh_auto.csv" > $OUT/summary_new_fresh_pooled.csv
# Results with a corner reported safe, paired (outside the criterion; safe_corners.py).
for seed in 61 71 41; do
  python3 $OUT/safe_corners.py $OUT/recognition_seed${seed}_d067_corners.csv auto=$OUT/recognition_seed${seed}_auto_corners.csv \
    > $OUT/safe_corners_seed$seed.csv
done
for v in d067 auto; do
  (cat $OUT/recognition_seed61_${v}_corners.csv; tail -n +2 $OUT/recognition_seed71_${v}_corners.csv) > "$WORK/new_fresh_${v}_corners.csv"
done
python3 $OUT/safe_corners.py "$WORK/new_fresh_d067_corners.csv" auto="$WORK/new_fresh_auto_corners.csv" \
  > $OUT/safe_corners_new_fresh_pooled.csv
# The identity check: seed 41 again, against the rows of the previous directory.
{
  echo "seed 41, d = 2/3 cm against the previous directory's d = 2/3 cm: $(python3 $OUT/same_rows.py $OUT/recognition_seed41_d067.csv $PREV/recognition_seed41_d067.csv)"
  echo "seed 41, automatic against the previous directory's d = 1 cm + soft_light: $(python3 $OUT/same_rows.py $OUT/recognition_seed41_auto.csv $PREV/recognition_seed41_d1_soft.csv)"
} > $OUT/identity_seed41.txt
python3 $OUT/safe_by_evidence.py d067=$OUT/recognition_seed61_d067_corners.csv,$OUT/recognition_seed71_d067_corners.csv \
  auto=$OUT/recognition_seed61_auto_corners.csv,$OUT/recognition_seed71_auto_corners.csv > $OUT/safe_by_evidence_new_fresh_pooled.csv
