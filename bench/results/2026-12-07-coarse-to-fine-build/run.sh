#!/usr/bin/env bash
# Reproduces this directory: the towel's thesis grid built with the coarse-to-fine rest-shape method
# (`drape_db build --rest-method quasi_static`, coarse levels 2 cm and 1 cm) beside today's d = 2/3 cm build,
# compared hold point by hold point and on the recognition benchmark on drapes the database did not make,
# and the per-hold-point cost ratio from runs interleaved in one process. Run from the repository root after
# setup.sh. It needs the d = 2/3 cm database and the held-out drapes of
# ../2026-12-07-automatic-step-tolerance/run.sh in $WORK (default /tmp/ab). About 1.5 h on the 2-core machine.
# The rows without the edge-length band (*_no_band*, and every 2 cm figure) were made with commit e25e5f8,
# before the band existed; this script, run today, gives the 2 cm level with the band.
set -u
D=.build/ws/devel/lib/textile_handling
OUT=bench/results/2026-12-07-coarse-to-fine-build
WORK=${WORK:-/tmp/ab}
export OMP_WAIT_POLICY=passive OMP_NUM_THREADS=1
COMMON="--textile towel --grid 6x6 --cg-tolerance 0.001 --cg-warm-start --threads 1 --sim-threads 1
        --spacing 0.006666666666666667 --rest-method quasi_static"
# The two builds side by side, one thread each (their wall times are indicative only).
$D/drape_db build --db "$WORK/qs2cm.sqlite" $COMMON --coarse-spacing 0.02 > "$OUT/build_qs2cm.log" 2>&1 &
$D/drape_db build --db "$WORK/qs1cm.sqlite" $COMMON --coarse-spacing 0.01 > "$OUT/build_qs1cm.log" 2>&1 &
wait
$D/drape_db build --db "$WORK/qs1cm_no_coarse_finish.sqlite" $COMMON --coarse-spacing 0.01 --no-coarse-finish \
  > "$OUT/build_qs1cm_no_coarse_finish.log" 2>&1
# Rest shapes against the d = 2/3 cm database, after the best turn about the hold axis.
for v in qs2cm qs1cm qs1cm_no_coarse_finish; do
  python3 bench/results/2026-12-07-automatic-step-tolerance/aligned_distance.py "$WORK/d067.sqlite" "$WORK/$v.sqlite" \
    > "$OUT/aligned_d067_$v.csv"
done
python3 bench/results/2026-12-07-automatic-step-tolerance/aligned_distance.py "$WORK/qs1cm.sqlite" \
  "$WORK/qs1cm_no_coarse_finish.sqlite" > "$OUT/aligned_qs1cm_qs1cm_no_coarse_finish.csv"
# Recognition of the same renders (the held-out drapes are copied next to each database's outputs).
for v in qs2cm qs1cm qs1cm_no_coarse_finish; do
  mkdir -p "$WORK/$v"
  cp "$WORK/d067/foreign_drapes.sqlite" "$WORK/$v/"
  $D/foreign_drape_bench --database "$WORK/$v.sqlite" --out "$WORK/$v" --holds 4 --views 3 --workers 1 --max-time 20 \
    > "$OUT/recognition_$v.log" 2>&1
  cp "$WORK/$v/foreign_drapes.csv" "$OUT/recognition_$v.csv"
  python3 bench/results/2026-12-07-automatic-step-tolerance/paired.py \
    bench/results/2026-12-07-automatic-step-tolerance/recognition_d067.csv "$OUT/recognition_$v.csv" > "$OUT/paired_d067_$v.csv"
done
# Cost: each hold point's dynamic run (CG 1e-3 warm, the d = 2/3 cm database's settings) and the coarse-to-fine
# run with the same solves, one after the other in one process; two processes (shards), one per core.
# The 2 cm level on both shards; the 1 cm level (with and without the coarse finish) on shard 0 only, 18 hold points.
holds() {  # NAME SHARD OPTIONS...
  local name=$1 k=$2; shift 2
  mkdir -p "$WORK/holds_${name}_$k" "$OUT/holds_$name"
  $D/drape_build_bench --out "$WORK/holds_${name}_$k" --spacings 0.006666666666666667 --mode holds --shard $k/2 \
    --fast quasi_static --fast-cg-tolerance 0.001 --fast-cg-warm-start \
    --reference-cg-tolerance 0.001 --reference-cg-warm-start "$@" > "$OUT/holds_$name/shard$k.log" 2>&1
  cp "$WORK/holds_${name}_$k/build_holds.csv" "$OUT/holds_$name/build_holds_shard$k.csv"
}
holds qs2cm 0 --coarse-spacing 0.02 & holds qs2cm 1 --coarse-spacing 0.02 & wait
holds qs1cm 0 --coarse-spacing 0.01 & holds qs1cm_no_coarse_finish 0 --coarse-spacing 0.01 --no-coarse-finish & wait
for name in qs2cm qs1cm qs1cm_no_coarse_finish; do python3 "$OUT/summarise_holds.py" "$OUT"/holds_$name/build_holds_shard*.csv; done
