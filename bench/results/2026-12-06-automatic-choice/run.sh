#!/usr/bin/env bash
# Reproduces this directory: the automatic choice on the three drape scenes of the speed/accuracy benchmark,
# placed among the particle and Choi-Ko configurations of every integrator (the rule never picks the yarn
# model for these scenes). Run from the repository root after setup.sh.
set -u
BENCH=.build/ws/devel/lib/textile_handling/speed_accuracy_bench
OUT=bench/results/2026-12-06-automatic-choice
export OMP_WAIT_POLICY=passive
$BENCH --auto --scenes towel_corner,towel_edge,table_drape --models particle_kes,choi_ko \
  --integrators semi_implicit,backward_euler_newton,rk4,block_diagonal --spacings 0.03,0.02,0.015,0.01 \
  --reference-spacing 0.0075 --repeats 3 --max-wall 30 --threads 1 --out $OUT > $OUT/automatic_choice.log 2>&1
