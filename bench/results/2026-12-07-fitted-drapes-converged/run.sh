#!/usr/bin/env bash
# Reproduces this directory: the yarn model's plain weave measured and fitted at d = 1 mm, its drape
# coefficient at 2 mm, the fitted cheap models' drape coefficients at 4 and 2 mm, KES bending on the 45 degree
# bias at 1, 2 and 4 mm for the three models, and the 10 cm square hung by a corner against the yarn model at
# 1 mm (speed_accuracy_bench). Run from the repository root after setup.sh; about 1 h on one core.
set -u
LAB=.build/ws/devel/lib/textile_handling/material_lab
BENCH=.build/ws/devel/lib/textile_handling/speed_accuracy_bench
OUT=bench/results/2026-12-07-fitted-drapes-converged
export OMP_WAIT_POLICY=passive
mkdir -p $OUT/bias45
# Lab figures and fits at 1 mm.
$LAB --model yarn_woven --model-option weave=plain --spacing 0.001 --tests bending,shear,tensile --fit particle_kes,choi_ko \
  --threads 1 --out $OUT/yarn_woven_plain_1mm > $OUT/yarn_woven_plain_1mm.log 2>&1; echo "yarn fit 1 mm exit $?" >> $OUT/exit_codes.txt
# Drape coefficients (the yarn model at 1 cm and 4 mm: ../2026-12-06-material-lab).
$LAB --model yarn_woven --model-option weave=plain --tests drape --drape-spacing 0.002 --threads 1 \
  --out $OUT/drape_yarn_woven_plain_0.002 > $OUT/drape_yarn_woven_plain_0.002.log 2>&1; echo "yarn drape 2 mm exit $?" >> $OUT/exit_codes.txt
for d in 0.004 0.002; do
  for m in choi_ko particle_kes; do
    $LAB --model $m --material $OUT/yarn_woven_plain_1mm/fitted_$m.yaml --tests drape --drape-spacing $d --threads 1 \
      --out $OUT/drape_fitted_${m}_$d > $OUT/drape_fitted_${m}_$d.log 2>&1; echo "fitted $m drape $d exit $?" >> $OUT/exit_codes.txt
  done
done
# Bending along the 45 degree bias (warp specimens) at three spacings.
for d in 0.001 0.002 0.004; do
  $LAB --model yarn_woven --model-option weave=plain --tests bending --directions warp --bending-bias-deg 45 --spacing $d \
    --out $OUT/bias45/yarn_woven_plain_$d > $OUT/bias45/yarn_woven_plain_$d.log 2>&1
  for m in particle_kes choi_ko; do
    $LAB --model $m --tests bending --directions warp --bending-bias-deg 45 --spacing $d --out $OUT/bias45/${m}_cotton_$d > /dev/null 2>&1
  done
done
$LAB --model yarn_woven --model-option weave=plain --tests bending --spacing 0.004 --out $OUT/bias45/yarn_woven_plain_principal_0.004 > /dev/null 2>&1
for d in 0.001 0.004; do
  $LAB --model yarn_woven --model-option weave=plain --model-option shear=false --model-option contact=false --model-option friction=false \
    --model-option sliding_friction=0 --tests bending --directions warp --bending-bias-deg 45 --spacing $d \
    --out $OUT/bias45/yarn_woven_plain_stretch_bending_only_$d > /dev/null 2>&1
done
# The 10 cm square hung by a corner, every run against the yarn model at 1 mm (reference settings).
$BENCH --scenes small_square_corner --models yarn_woven,particle_kes,choi_ko --model-option yarn_woven:weave=plain \
  --material particle_kes=$OUT/yarn_woven_plain_1mm/fitted_particle_kes.yaml --material choi_ko=$OUT/yarn_woven_plain_1mm/fitted_choi_ko.yaml \
  --integrators semi_implicit --spacings 0.01,0.005,0.004,0.002 --reference-model yarn_woven --reference-spacing 0.001 --repeats 3 \
  --max-wall 900 --reference-max-wall 1800 --threads 1 --out $OUT/small_square > $OUT/small_square.log 2>&1
# The fitted Choi-Ko model against its own 1 mm drape on the 10 cm square (one round).
$BENCH --scenes small_square_corner --models choi_ko --material choi_ko=$OUT/yarn_woven_plain_1mm/fitted_choi_ko.yaml \
  --integrators semi_implicit --spacings 0.01,0.005,0.004,0.002 --reference-spacing 0.001 --repeats 1 \
  --max-wall 900 --reference-max-wall 1800 --threads 1 --out $OUT/small_square_choi_ko_self > $OUT/small_square_choi_ko_self.log 2>&1
# The fitted Choi-Ko material with its bending curves scaled, mirror images allowed: on the 10 cm square against the
# yarn model at 1 mm, and on the 30 cm square against the yarn model at 4 mm (the two ran side by side).
$BENCH --scenes small_square_corner --models yarn_woven,choi_ko --model-option yarn_woven:weave=plain \
  --material choi_ko=$OUT/yarn_woven_plain_1mm/fitted_choi_ko.yaml --bending-scales choi_ko=1,2,3,4,6 --align-mirror \
  --integrators semi_implicit --spacings 0.01,0.005,0.004 --reference-model yarn_woven --reference-spacing 0.001 --repeats 3 \
  --max-wall 900 --reference-max-wall 1800 --threads 1 --out $OUT/small_square_bending_scales > $OUT/small_square_bending_scales.log 2>&1
$BENCH --scenes square_corner --models yarn_woven,choi_ko --model-option yarn_woven:weave=plain \
  --material choi_ko=$OUT/yarn_woven_plain_1mm/fitted_choi_ko.yaml --bending-scales choi_ko=1,2,3,4,6 --align-mirror \
  --integrators semi_implicit --spacings 0.01,0.005 --reference-model yarn_woven --reference-spacing 0.004 --repeats 3 \
  --max-wall 900 --reference-max-wall 1800 --threads 1 --out $OUT/square_bending_scales > $OUT/square_bending_scales.log 2>&1
# One model's own resolutions with mirror images allowed (towels, cotton, against 0.75 cm; one round).
$BENCH --scenes towel_corner,towel_edge --models particle_kes,choi_ko --integrators semi_implicit --spacings 0.03,0.02,0.015,0.01 \
  --reference-spacing 0.0075 --align-mirror --repeats 1 --max-wall 300 --threads 1 --out $OUT/towel_mirror > $OUT/towel_mirror.log 2>&1
# The fitted Choi-Ko model's own bending curve at 1 mm (its soft start below the buckling onset).
$LAB --model choi_ko --material $OUT/yarn_woven_plain_1mm/fitted_choi_ko.yaml --tests bending --directions warp --spacing 0.001 \
  --out $OUT/bending_fitted_choi_ko_0.001 > /dev/null 2>&1
# Choi-Ko's buckling onset s* (the linear segment below it carries moments growing like kappa^3): the default 0.999 and
# 0.9999 on the 10 cm square at 4 mm, against the yarn model at 2 mm (reference settings).
for s in 0.999 0.9999; do
  $BENCH --scenes small_square_corner --models yarn_woven,choi_ko --model-option yarn_woven:weave=plain --model-option choi_ko:buckling_onset=$s \
    --material choi_ko=$OUT/yarn_woven_plain_1mm/fitted_choi_ko.yaml --bending-scales choi_ko=1,2 --align-mirror --integrators semi_implicit \
    --spacings 0.004 --reference-model yarn_woven --reference-spacing 0.002 --repeats 3 --max-wall 900 --threads 1 \
    --out $OUT/small_square_onset_$s > $OUT/small_square_onset_$s.log 2>&1
done
# The 30 cm square with a 25 s cap (its drapes still move at 8 s): the bending scales at the default onset, and the onset
# 0.9999 (the two ran side by side).
$BENCH --scenes square_corner --models yarn_woven,choi_ko --model-option yarn_woven:weave=plain \
  --material choi_ko=$OUT/yarn_woven_plain_1mm/fitted_choi_ko.yaml --bending-scales choi_ko=1,2,4 --align-mirror --max-sim-time 25 \
  --integrators semi_implicit --spacings 0.01,0.005 --reference-model yarn_woven --reference-spacing 0.004 --repeats 3 \
  --max-wall 900 --reference-max-wall 2400 --threads 1 --out $OUT/square_bending_scales_25s > $OUT/square_bending_scales_25s.log 2>&1
$BENCH --scenes square_corner --models yarn_woven,choi_ko --model-option yarn_woven:weave=plain --model-option choi_ko:buckling_onset=0.9999 \
  --material choi_ko=$OUT/yarn_woven_plain_1mm/fitted_choi_ko.yaml --bending-scales choi_ko=1,2 --align-mirror --max-sim-time 25 \
  --integrators semi_implicit --spacings 0.005 --reference-model yarn_woven --reference-spacing 0.004 --repeats 3 \
  --max-wall 900 --reference-max-wall 2400 --threads 1 --out $OUT/square_onset_0.9999_25s > $OUT/square_onset_0.9999_25s.log 2>&1
# The fitted Choi-Ko material with the onset given as a curvature (5 1/m), bending x1 and x2, on the 10 cm square against the
# yarn model at 1 mm.
$BENCH --scenes small_square_corner --models yarn_woven,choi_ko --model-option yarn_woven:weave=plain \
  --model-option choi_ko:buckling_onset_curvature_per_m=5 --material choi_ko=$OUT/yarn_woven_plain_1mm/fitted_choi_ko.yaml \
  --bending-scales choi_ko=1,2 --align-mirror --integrators semi_implicit --spacings 0.01,0.005,0.004,0.002 --reference-model yarn_woven \
  --reference-spacing 0.001 --repeats 3 --max-wall 900 --reference-max-wall 1800 --threads 1 \
  --out $OUT/small_square_onset_curvature > $OUT/small_square_onset_curvature.log 2>&1
