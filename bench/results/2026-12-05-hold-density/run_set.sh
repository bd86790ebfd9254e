#!/bin/bash
# run_set.sh OUT SET DB [extra foreign_drape_bench args]: one held-out set recognised against DB.
# The held-out drapes are not rebuilt: HELD_OUT_DIR/<src>/foreign_drapes.sqlite must hold the set's
# cached drapes (built by the first foreign_drape_bench run with the same --holds/--seed/--variants;
# ../2026-12-05-depth-all-images/README.md). BIN: the foreign_drape_bench binary.
set -euo pipefail
BIN=${BIN:-foreign_drape_bench}
OUT=$1; SET=$2; DB=$3; shift 3
export OMP_WAIT_POLICY=passive OMP_NUM_THREADS=1
case $SET in
 seed1) src=s1; args="--holds 4 --views 3 --seed 1 --variants choi_ko,stiff_light,soft_heavy,heap";;
 seed11) src=s11; args="--holds 6 --views 3 --seed 11 --variants choi_ko,stiff_light,soft_heavy";;
 seed31) src=s31; args="--holds 4 --views 3 --seed 31 --variants choi_ko,stiff_light,soft_heavy,heap";;
 thesis_seed1) src=th; args="--holds 4 --views 3 --seed 1 --variants thesis";;
 *) echo "unknown set $SET (seed1, seed11, seed31, thesis_seed1)" >&2; exit 2;;
esac
mkdir -p "$OUT/$SET"; cp "$HELD_OUT_DIR/$src/foreign_drapes.sqlite" "$OUT/$SET/"
"$BIN" --database "$DB" --out "$OUT/$SET" --workers 1 --max-time 20 $args "$@" > "$OUT/$SET/foreign_drapes.log" 2>&1
