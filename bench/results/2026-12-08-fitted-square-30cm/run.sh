#!/usr/bin/env bash
# Reproduces this directory: the 30 x 30 cm square hung by a corner (scene square_corner), the yarn model's plain
# weave at 3 mm as the reference (25 s cap), against
#  (a) the yarn model at 1 cm and 5 mm and Choi-Ko with the cantilever-fitted material (kappa* = 5 1/m) at 1 cm and
#      5 mm, 3 interleaved rounds (cost as the ratio to the yarn model's 1 cm run in the same round);
#  (b) the yarn model and the fitted Choi-Ko at 4 mm, one round (how far the yarn model has converged at 3 mm).
# The two benches run side by side, one thread each; each simulates the 3 mm reference itself. Run from the
# repository root after scripts/setup.sh; about 40 min on the 2-core machine.
set -u
BENCH=.build/ws/devel/lib/textile_handling/speed_accuracy_bench
OUT=bench/results/2026-12-08-fitted-square-30cm
FIT=bench/results/2026-12-07-cantilever-fit/yarn_woven_plain_1mm_fit_choi_ko_4mm/fitted_choi_ko.yaml
export OMP_WAIT_POLICY=passive OMP_NUM_THREADS=1
COMMON="--scenes square_corner --models yarn_woven,choi_ko --model-option yarn_woven:weave=plain
  --model-option choi_ko:buckling_onset_curvature_per_m=5 --material choi_ko=$FIT --align-mirror --max-sim-time 25
  --integrators semi_implicit --reference-model yarn_woven --reference-spacing 0.003 --max-wall 1800
  --reference-max-wall 3600 --threads 1"
$BENCH $COMMON --spacings 0.01,0.005 --repeats 3 --out $OUT/rounds > $OUT/rounds.log 2>&1 &
$BENCH $COMMON --spacings 0.004 --repeats 1 --out $OUT/at_4mm > $OUT/at_4mm.log 2>&1 &
wait
