#!/usr/bin/env bash
# ABBA-ordered runs of two drape_sim builds (1 thread) on one scene of this folder; appends
# "tag scene old|new seconds" lines to OUT.
# Usage: OLD=/path/to/old/drape_sim OLD_LIB=/path/to/old/lib NEW=/path/to/new/drape_sim \
#        bash run_abba_pairs.sh SCENE REPS OUT
set -eu
cd "$(dirname "$0")"
export OMP_WAIT_POLICY=passive
scene=$1; reps=$2; out=$3
one() {
  local v=$1 tag=$2 bin lib
  if [ "$v" = old ]; then bin=$OLD; lib=${OLD_LIB:-}; else bin=$NEW; lib=${NEW_LIB:-}; fi
  local t0 t1
  t0=$(date +%s.%N); LD_LIBRARY_PATH=$lib "$bin" "$scene.yaml" --out "/tmp/abba-$v-$tag" --threads 1 > /dev/null 2>&1; t1=$(date +%s.%N)
  echo "$tag $scene $v $(echo "$t1 - $t0" | bc)" >> "$out"
}
for i in $(seq 1 "$reps"); do one old "a$i"; one new "a$i"; one new "b$i"; one old "b$i"; done
