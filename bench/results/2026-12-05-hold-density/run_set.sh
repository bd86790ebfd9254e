#!/bin/bash
# run1.sh OUT SET DB [extra args]: one held-out set against DB
B=/work/main/.build/ws/devel/lib/textile_handling/foreign_drape_bench
OUT=$1; SET=$2; DB=$3; shift 3
export OMP_WAIT_POLICY=passive OMP_NUM_THREADS=1
case $SET in
 seed1) src=s1; args="--holds 4 --views 3 --seed 1 --variants choi_ko,stiff_light,soft_heavy,heap";;
 seed11) src=s11; args="--holds 6 --views 3 --seed 11 --variants choi_ko,stiff_light,soft_heavy";;
 seed31) src=s31; args="--holds 4 --views 3 --seed 31 --variants choi_ko,stiff_light,soft_heavy,heap";;
 seed41) src=s41; args="--holds 4 --views 3 --seed 41 --variants choi_ko,stiff_light,soft_heavy,heap";;
 thesis_seed1) src=th; args="--holds 4 --views 3 --seed 1 --variants thesis";;
esac
mkdir -p $OUT/$SET; cp /tmp/fb/$src/foreign_drapes.sqlite $OUT/$SET/
$B --database $DB --out $OUT/$SET --workers 1 --max-time 20 $args "$@" > $OUT/$SET/foreign_drapes.log 2>&1
