#!/usr/bin/env bash
# Reproduces this directory: material_lab on the three models at d = 2 mm (the drape coefficient at 1 cm) (cotton for the particle-level
# models, the bundled woven fabrics for the yarn model, each fitted by particle_kes and choi_ko). Run from the repository root after setup.sh.
set -u
LAB=.build/ws/devel/lib/textile_handling/material_lab
OUT=bench/results/2026-12-06-material-lab
export OMP_WAIT_POLICY=passive
$LAB --model particle_kes --out $OUT/particle_kes_cotton > $OUT/particle_kes_cotton.log 2>&1; echo "particle_kes exit $?" >> $OUT/exit_codes.txt
$LAB --model choi_ko --out $OUT/choi_ko_cotton > $OUT/choi_ko_cotton.log 2>&1; echo "choi_ko exit $?" >> $OUT/exit_codes.txt
for weave in plain twill_2_2 satin_5; do
  $LAB --model yarn_woven --model-option weave=$weave --tests bending,shear,tensile,drape --fit particle_kes,choi_ko --out $OUT/yarn_woven_$weave \
    > $OUT/yarn_woven_$weave.log 2>&1; echo "yarn_woven $weave exit $?" >> $OUT/exit_codes.txt
done
# The plain fabric measured and draped at one resolution, 4 mm (the finest at which the 1 cm yarn drape
# and the KES bending arc, kappa d <= 1 at 2.5 1/cm, both run), with both fits.
$LAB --model yarn_woven --model-option weave=plain --spacing 0.004 --drape-spacing 0.004 --tests bending,shear,tensile,drape \
  --fit particle_kes,choi_ko --out $OUT/yarn_woven_plain_4mm > $OUT/yarn_woven_plain_4mm.log 2>&1; echo "yarn_woven plain 4 mm exit $?" >> $OUT/exit_codes.txt
# The plain fabric's trellis shear taken to 40 degrees (KES stops at 8).
$LAB --model yarn_woven --model-option weave=plain --tests shear --directions warp --shear-max-angle 40 \
  --out $OUT/yarn_woven_plain_shear40 > $OUT/yarn_woven_plain_shear40.log 2>&1; echo "yarn_woven plain shear to 40 deg exit $?" >> $OUT/exit_codes.txt
# The plain fabric's drape (1 cm) with one crossing term of the yarn model switched off at a time.
for opt in contact=false friction=false shear=false sliding_friction=0; do
  $LAB --model yarn_woven --model-option weave=plain --model-option $opt --tests drape --out $OUT/yarn_woven_plain_drape_$opt \
    > $OUT/yarn_woven_plain_drape_$opt.log 2>&1; echo "yarn_woven plain drape $opt exit $?" >> $OUT/exit_codes.txt
done
# Deformations the KES pieces do not impose: bending on the 45-degree bias (yarn plain and its two fits,
# warp specimens), and shear under a 2 % pretension of the crossing yarns (yarn plain).
$LAB --model yarn_woven --model-option weave=plain --tests bending --directions warp --bending-bias-deg 45 \
  --out $OUT/bias45_yarn_woven_plain > $OUT/bias45_yarn_woven_plain.log 2>&1; echo "bias 45 yarn exit $?" >> $OUT/exit_codes.txt
for m in particle_kes choi_ko; do
  $LAB --model $m --material $OUT/yarn_woven_plain/fitted_$m.yaml --tests bending --directions warp --bending-bias-deg 45 \
    --out $OUT/bias45_fitted_$m > $OUT/bias45_fitted_$m.log 2>&1; echo "bias 45 fitted $m exit $?" >> $OUT/exit_codes.txt
done
$LAB --model yarn_woven --model-option weave=plain --tests shear --directions warp --shear-pretension-strain 0.02 \
  --out $OUT/pretension2pct_yarn_woven_plain > $OUT/pretension2pct_yarn_woven_plain.log 2>&1; echo "pretension yarn exit $?" >> $OUT/exit_codes.txt
