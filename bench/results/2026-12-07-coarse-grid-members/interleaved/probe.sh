#!/usr/bin/env bash
# Per-hold-point cost of d = 1 cm + soft_light against d = 2/3 cm, interleaved: on each hold point the d = 2/3 cm
# simulation, then the d = 1 cm base and soft_light simulations, one after the other in one process; two such
# processes (hold-point shards), one per core. Usage: probe.sh SHARD (0 or 1); writes times_SHARD.csv.
set -u
cd "$(dirname "$0")/../../../.."
D=.build/ws/devel/lib/textile_handling
OUT=bench/results/2026-12-07-coarse-grid-members/interleaved
W=${WORK:-/tmp/mb2}/interleaved
mkdir -p "$W"
export OMP_WAIT_POLICY=passive OMP_NUM_THREADS=1
COMMON="--textile towel --cg-tolerance 0.001 --cg-warm-start --threads 1 --sim-threads 1 --quiet --no-symmetry"
if [ "$1" = 0 ]; then HOLDS="0,0.46 0.192,0.046 0.064,0.184 0.32,0.23 0.128,0.092 0.256,0.138"
else HOLDS="0.064,0 0.32,0.092 0.128,0.23 0.256,0.046 0,0.138 0.192,0.184"; fi
echo "hold,d067_s,d1_base_s,d1_soft_light_s" > "$OUT/times_$1.csv"
t() { local s=$(date +%s.%N); "$@" > /dev/null 2>&1; echo "$(date +%s.%N) - $s" | bc; }
for h in $HOLDS; do
  a=$(t $D/drape_db build --db "$W/d067_$h.sqlite" --hold $h --spacing 0.006666666666666667 $COMMON)
  b=$(t $D/drape_db build --db "$W/d1_$h.sqlite" --hold $h --spacing 0.01 $COMMON)
  c=$(t $D/drape_db build --db "$W/d1_$h.sqlite" --hold $h --spacing 0.01 --members soft_light $COMMON)
  echo "\"$h\",$a,$b,$c" >> "$OUT/times_$1.csv"
done
