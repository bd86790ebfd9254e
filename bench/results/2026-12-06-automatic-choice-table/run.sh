#!/usr/bin/env bash
# Reproduces this directory: the automatic choice (every finer candidate must agree) on the table drape,
# placed among the particle and Choi-Ko configurations of every integrator, as in
# ../2026-12-06-automatic-choice/ (whose towel scenes the rule change leaves as they were). Run from the
# repository root after setup.sh.
set -u
BENCH=.build/ws/devel/lib/textile_handling/speed_accuracy_bench
OUT=bench/results/2026-12-06-automatic-choice-table
export OMP_WAIT_POLICY=passive
$BENCH --auto --scenes table_drape --models particle_kes,choi_ko \
  --integrators semi_implicit,backward_euler_newton,rk4,block_diagonal --spacings 0.03,0.02,0.015,0.01 \
  --reference-spacing 0.0075 --repeats 3 --max-wall 30 --threads 1 --out $OUT > $OUT/automatic_choice.log 2>&1
