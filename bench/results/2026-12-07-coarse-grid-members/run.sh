#!/usr/bin/env bash
# Reproduces this directory: towel databases at d = 1 cm with extra members (other materials, a tilted start)
# and at d = 1/2 cm, built beside today's d = 2/3 cm database and recognised on two held-out sets of drapes the
# database did not make: the seed-1 set of ../2026-12-07-automatic-step-tolerance/ (27 drapes) and a fresh seed-41
# set. Run from the repository root after setup.sh, with that directory's $WORK/d067/foreign_drapes.sqlite in
# place (its run.sh makes it). About 2.5 h on the 2-core machine. Scratch files go to $WORK.
set -u
D=.build/ws/devel/lib/textile_handling
OUT=bench/results/2026-12-07-coarse-grid-members
WORK=${WORK:-/tmp/mb2}
SEED1=${SEED1:-/tmp/ab/d067/foreign_drapes.sqlite}
REFERENCE_DB=${REFERENCE_DB:-/tmp/ab/d067.sqlite}  # that directory's d = 2/3 cm database
export OMP_WAIT_POLICY=passive OMP_NUM_THREADS=1
mkdir -p "$WORK"
COMMON="--textile towel --grid 6x6 --cg-tolerance 0.001 --cg-warm-start --threads 1 --sim-threads 1 --quiet"
timed() {  # NAME COMMAND...: runs the command, appends "NAME seconds" to times.txt
  local name=$1 s; shift; s=$(date +%s); "$@"; echo "$name $(( $(date +%s) - s ))" >> "$OUT/times.txt"
}
# Side by side, one thread each: d = 2/3 cm on one core; d = 1 cm and its members one after the other on the other.
timed d067 $D/drape_db build --db "$WORK/d067.sqlite" --spacing 0.006666666666666667 $COMMON &
(
  timed d1 $D/drape_db build --db "$WORK/d1.sqlite" --spacing 0.01 $COMMON
  cp "$WORK/d1.sqlite" "$WORK/d1_soft.sqlite"
  timed soft_light $D/drape_db build --db "$WORK/d1_soft.sqlite" --spacing 0.01 --members soft_light $COMMON
  cp "$WORK/d1_soft.sqlite" "$WORK/d1_soft_stiff.sqlite"
  timed stiff_heavy $D/drape_db build --db "$WORK/d1_soft_stiff.sqlite" --spacing 0.01 --members stiff_heavy $COMMON
  cp "$WORK/d1.sqlite" "$WORK/d1_tilted.sqlite"
  timed tilted $D/drape_db build --db "$WORK/d1_tilted.sqlite" --spacing 0.01 --members tilted $COMMON
) &
wait
# d = 1/2 cm, two workers, beside the seed-41 held-out drapes (one worker).
mkdir -p "$WORK/s41"
timed d05_two_workers $D/drape_db build --db "$WORK/d05.sqlite" --spacing 0.005 \
  --textile towel --grid 6x6 --cg-tolerance 0.001 --cg-warm-start --threads 2 --sim-threads 1 --quiet &
# The fresh sets (seeds 41, 51) without the two self-collision variants (their held-out simulations are the slow ones).
FRESH_VARIANTS=choi_ko,stiff_light,soft_heavy,heap,thesis
$D/foreign_drape_bench --database "$WORK/none.sqlite" --out "$WORK/s41" --holds 4 --views 3 --seed 41 --workers 2 \
  --variants $FRESH_VARIANTS --max-time 20 > "$OUT/heldout_s41.log" 2>&1 &
wait
python3 bench/results/2026-12-06-automatic-build/compare_builds.py "$REFERENCE_DB" "$WORK/d067.sqlite" \
  > "$OUT/compare_d067_rebuilt.csv"
recognise() {  # SET DATABASE: the set's renders recognised against $WORK/DATABASE.sqlite
  local set=$1 v=$2 dir="$WORK/$1_$2"
  mkdir -p "$dir"
  local only=()
  case $set in
    seed1) cp "$SEED1" "$dir/" ;;
    seed41|seed51)  # the fresh sets: held-out drapes in $WORK/s41, $WORK/s51
      cp "$WORK/s${set#seed}/foreign_drapes.sqlite" "$dir/"; only=(--seed "${set#seed}" --variants $FRESH_VARIANTS) ;;
  esac
  $D/foreign_drape_bench --database "$WORK/$v.sqlite" --out "$dir" --holds 4 --views 3 "${only[@]}" --workers 1 \
    --max-time 20 > "$OUT/recognition_${set}_$v.log" 2>&1
  cp "$dir/foreign_drapes.csv" "$OUT/recognition_${set}_$v.csv"
}
for v in d1 d1_soft d1_soft_stiff d1_tilted d05; do recognise seed1 $v; done
recognise seed41 d067 & recognise seed41 d1_soft & wait
recognise seed41 d1 & recognise seed41 d05 & wait
S1REF=bench/results/2026-12-07-automatic-step-tolerance/recognition_d067.csv
python3 $OUT/summarise.py $S1REF d1=$OUT/recognition_seed1_d1.csv d1_soft=$OUT/recognition_seed1_d1_soft.csv \
  d1_soft_stiff=$OUT/recognition_seed1_d1_soft_stiff.csv d1_tilted=$OUT/recognition_seed1_d1_tilted.csv \
  d05=$OUT/recognition_seed1_d05.csv > $OUT/summary_seed1.csv
python3 $OUT/summarise.py $OUT/recognition_seed41_d067.csv d1=$OUT/recognition_seed41_d1.csv \
  d1_soft=$OUT/recognition_seed41_d1_soft.csv d05=$OUT/recognition_seed41_d05.csv > $OUT/summary_seed41.csv
# Interleaved cost on 12 hold points, two shards side by side, after everything above.
$OUT/interleaved/probe.sh 0 & $OUT/interleaved/probe.sh 1 & wait
python3 $OUT/interleaved/summarise_times.py $OUT/interleaved/times_*.csv > $OUT/interleaved/summary.txt
# A second fresh set (seed 51), made and recognised after everything above.
mkdir -p "$WORK/s51"
$D/foreign_drape_bench --database "$WORK/none.sqlite" --out "$WORK/s51" --holds 4 --views 3 --seed 51 --workers 2 \
  --variants $FRESH_VARIANTS --max-time 20 > "$OUT/heldout_s51.log" 2>&1
recognise seed51 d067 & recognise seed51 d1_soft & wait
recognise seed51 d05 & recognise seed51 d1 & wait
python3 $OUT/summarise.py $OUT/recognition_seed51_d067.csv d1=$OUT/recognition_seed51_d1.csv \
  d1_soft=$OUT/recognition_seed51_d1_soft.csv d05=$OUT/recognition_seed51_d05.csv > $OUT/summary_seed51.csv
for v in d067 d1 d1_soft d05; do  # the fresh sets pooled
  (cat $OUT/recognition_seed41_$v.csv; tail -n +2 $OUT/recognition_seed51_$v.csv) > "$WORK/fresh_$v.csv"
done
python3 $OUT/summarise.py "$WORK/fresh_d067.csv" d1="$WORK/fresh_d1.csv" d1_soft="$WORK/fresh_d1_soft.csv" \
  d05="$WORK/fresh_d05.csv" > $OUT/summary_fresh_pooled.csv
