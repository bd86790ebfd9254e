#!/usr/bin/env bash
# Reproduces this directory: the yarn model's plain weave measured at d = 1 mm and Choi-Ko (onset curvature
# 5 1/m) fitted to its cantilever at 4 mm; cantilever readings of both models and of Choi-Ko variants; drape
# coefficients of the cantilever-fitted and the KES-fitted Choi-Ko; the two small sheets hung against the
# yarn model at 1 mm (8 s and 25 s caps). Run from the repository root after setup.sh; about 1.5 h on one core.
set -u
LAB=.build/ws/devel/lib/textile_handling/material_lab
BENCH=.build/ws/devel/lib/textile_handling/speed_accuracy_bench
OUT=bench/results/2026-12-07-cantilever-fit
KES=bench/results/2026-12-07-fitted-drapes-converged/yarn_woven_plain_1mm/fitted_choi_ko.yaml
export OMP_WAIT_POLICY=passive
FIT=$OUT/yarn_woven_plain_1mm_fit_choi_ko_4mm
CK="--model choi_ko --model-option buckling_onset_curvature_per_m=5"
# The fit (the same at --fit-spacing 0.002 stopped: Choi-Ko's cantilever static solve did not converge).
$LAB --model yarn_woven --model-option weave=plain --spacing 0.001 --tests bending,shear,tensile,cantilever \
  --fit choi_ko --fit-model-option choi_ko:buckling_onset_curvature_per_m=5 --fit-bending cantilever --fit-spacing 0.004 \
  --threads 1 --out $FIT > $FIT.log 2>&1
# The same fit for the twill and the satin.
for w in twill_2_2 satin_5; do
  $LAB --model yarn_woven --model-option weave=$w --spacing 0.001 --tests bending,shear,tensile,cantilever \
    --fit choi_ko --fit-model-option choi_ko:buckling_onset_curvature_per_m=5 --fit-bending cantilever --fit-spacing 0.004 \
    --threads 1 --out $OUT/yarn_woven_${w}_1mm_fit_choi_ko_4mm > $OUT/yarn_woven_${w}_1mm_fit_choi_ko_4mm.log 2>&1
done
# Cantilever readings (cantilever_readings/): the yarn model at 2 and 1 mm; the KES-fitted Choi-Ko at 2 and 4 mm
# (and 2 mm with the default onset, and with Y x 53); the cantilever-fitted Choi-Ko at 4 mm with variants.
R=$OUT/cantilever_readings
$LAB --model yarn_woven --model-option weave=plain --spacing 0.002 --tests cantilever --directions warp --out $R/cant_yarn2 > /dev/null
$LAB --model yarn_woven --model-option weave=plain --spacing 0.001 --tests cantilever --out $R/cant_yarn1 > /dev/null
$LAB $CK --material $KES --spacing 0.002 --tests cantilever,bending --directions warp --out $R/cant_ck2 > /dev/null
$LAB $CK --material $KES --spacing 0.004 --tests cantilever --directions warp --out $R/cant_ck_0.004 > /dev/null
$LAB --model choi_ko --material $KES --spacing 0.002 --tests cantilever --directions warp --out $R/cant_ckdef_0.002 > /dev/null
sed "s/^tension_stiffness_N_m: .*/tension_stiffness_N_m: 1e11/" $KES > /tmp/ck_t1e11.yaml
$LAB $CK --material /tmp/ck_t1e11.yaml --spacing 0.002 --tests cantilever --directions warp --out $R/cant_ck2_t1e11 > /dev/null
M=$FIT/fitted_choi_ko.yaml
mech() { n=$1; shift; $LAB --model choi_ko --material $M "$@" --spacing 0.004 --tests bending,cantilever --directions warp \
  --out $R/fit_mech_$n > /dev/null; }
mech base --model-option buckling_onset_curvature_per_m=5
mech plate --model-option buckling_onset_curvature_per_m=5 --model-option bending_version=plate
mech stiffT --model-option buckling_onset_curvature_per_m=5 --model-option tensile_stiffness_N_m=1e5
mech noshear --model-option buckling_onset_curvature_per_m=5 --model-option shear=false
mech k1 --model-option buckling_onset_curvature_per_m=1
mech k20 --model-option buckling_onset_curvature_per_m=20
mech default
# Drape coefficients of the two fitted materials (the yarn model's: ../2026-12-07-fitted-drapes-converged).
for d in 0.004 0.01; do
  $LAB $CK --material $M --tests drape --drape-spacing $d --threads 1 --out $OUT/drape_cantilever_fit_$d > $OUT/drape_cantilever_fit_$d.log 2>&1
  $LAB $CK --material $KES --tests drape --drape-spacing $d --threads 1 --out $OUT/drape_kes_fit_$d > $OUT/drape_kes_fit_$d.log 2>&1
done
# The two small sheets against the yarn model at 1 mm: the cantilever fit (x1) and, for contrast, its bending
# curves times 0.46 (about the KES fit's), 8 s cap; then the fit alone with a 25 s cap.
$BENCH --scenes small_square_corner,small_sheet_edge --models yarn_woven,choi_ko --model-option yarn_woven:weave=plain \
  --model-option choi_ko:buckling_onset_curvature_per_m=5 --material choi_ko=$M --bending-scales choi_ko=1,0.46 --align-mirror \
  --integrators semi_implicit --spacings 0.01,0.005,0.004 --reference-model yarn_woven --reference-spacing 0.001 --repeats 3 \
  --max-wall 900 --reference-max-wall 1800 --threads 1 --out $OUT/small_sheets > $OUT/small_sheets.log 2>&1
$BENCH --scenes small_sheet_edge,small_square_corner --models yarn_woven,choi_ko --model-option yarn_woven:weave=plain \
  --model-option choi_ko:buckling_onset_curvature_per_m=5 --material choi_ko=$M --align-mirror \
  --integrators semi_implicit --spacings 0.01,0.005,0.004 --reference-model yarn_woven --reference-spacing 0.001 --repeats 3 \
  --max-sim-time 25 --max-wall 900 --reference-max-wall 3600 --threads 1 --out $OUT/small_sheets_25s > $OUT/small_sheets_25s.log 2>&1
