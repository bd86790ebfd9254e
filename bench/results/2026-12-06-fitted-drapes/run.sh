#!/usr/bin/env bash
# Reproduces this directory: the yarn model's plain weave against particle_kes and choi_ko with the materials
# fitted to it (bench/results/2026-12-06-material-lab/yarn_woven_plain), hung by a corner, every run compared
# with the yarn model at 1 cm. Run from the repository root after setup.sh.
set -u
BENCH=.build/ws/devel/lib/textile_handling/speed_accuracy_bench
OUT=bench/results/2026-12-06-fitted-drapes
FIT=bench/results/2026-12-06-material-lab/yarn_woven_plain
export OMP_WAIT_POLICY=passive
$BENCH --scenes square_corner,towel_corner --models yarn_woven,particle_kes,choi_ko --model-option yarn_woven:weave=plain \
  --material particle_kes=$FIT/fitted_particle_kes.yaml --material choi_ko=$FIT/fitted_choi_ko.yaml \
  --integrators semi_implicit --spacings 0.02,0.01 --reference-model yarn_woven --reference-spacing 0.01 --repeats 3 \
  --max-wall 600 --threads 1 --out $OUT > $OUT/fitted_drapes.log 2>&1
