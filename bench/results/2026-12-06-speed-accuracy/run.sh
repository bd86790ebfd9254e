#!/usr/bin/env bash
# Reproduces this directory: speed_accuracy_bench on the four scenes, split over two processes of
# one thread each (the hanging towels; the table drape and the compression). Run from the repository root
# after setup.sh.
set -u
BENCH=.build/ws/devel/lib/textile_handling/speed_accuracy_bench
OUT=bench/results/2026-12-06-speed-accuracy
export OMP_WAIT_POLICY=passive
COMMON="--models particle_kes,choi_ko,yarn_woven --integrators semi_implicit,backward_euler_newton,rk4,block_diagonal
  --spacings 0.03,0.02,0.015,0.01 --reference-spacing 0.0075 --repeats 3 --max-wall 30 --reference-max-wall 600 --threads 1"
$BENCH --scenes towel_corner,towel_edge $COMMON --out $OUT/hanging > $OUT/hanging.log 2>&1 &
$BENCH --scenes table_drape,pushed_edges $COMMON --out $OUT/table_compression > $OUT/table_compression.log 2>&1
wait
