#!/usr/bin/env bash
# Error-tolerance probe: per hold point, the builder's default (0.1 mm) and a looser tolerance, alternating.
set -u
mkdir -p ${WORK:-/tmp/probe}
D=.build/ws/devel/lib/textile_handling   # run from the repository root
export OMP_WAIT_POLICY=passive OMP_NUM_THREADS=1
COMMON="--textile towel --spacing 0.006666666666666667 --cg-tolerance 0.001 --cg-warm-start --threads 1 --sim-threads 1 --quiet"
for h in 0,0.46 0.192,0.046 0.128,0.138 0.32,0.23; do
  for tol in 0.0001 0.0003 0.001; do
    s=$(date +%s.%N)
    $D/drape_db build --db ${WORK:-/tmp/probe}/tol$tol.sqlite --hold $h --tolerance $tol $COMMON > ${WORK:-/tmp/probe}/tol${tol}_$h.log 2>&1
    echo "$h,$tol,$?,$(echo "$(date +%s.%N) - $s" | bc)" >> ${WORK:-/tmp/probe}/times.csv
  done
done
