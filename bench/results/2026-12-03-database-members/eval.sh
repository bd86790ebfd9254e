#!/bin/bash
# eval.sh NAME DB : foreign bench (seed 1, 4 holds, choi_ko/stiff_light/soft_heavy/heap) against DB into /tmp/mem/ev_NAME
set -e
D=/tmp/mem/ev_$1
mkdir -p $D
cp /tmp/mem/ev1_replay/foreign_drapes.sqlite $D/
cd $D
OMP_WAIT_POLICY=passive OMP_NUM_THREADS=1 /work/main/.build/ws/devel/lib/textile_handling/foreign_drape_bench --database $2 --out $D --holds 4 --views 3 --seed 1 --workers 1 --max-time 20 --variants choi_ko,stiff_light,soft_heavy,heap > run.log 2>&1
