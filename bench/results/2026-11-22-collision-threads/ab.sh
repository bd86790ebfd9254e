#!/bin/bash
# Interleaved timing runs of drape_sim builds: ab.sh SCENE THREADS REPS NAME...
# For every NAME, /tmp/drape_sim_NAME is run against the libraries in /tmp/lib_NAME (copies of
# devel/lib/libtextile_handling_sim_core.so and libtextile_handling_sim_picture.so of that build).
# Prints one line per run: steps, rejected steps, wall time, collision ms/step with the broad
# phase / proximity stage / crossing detection split, assembly ms/step and their ratio.
scene=$1; t=$2; reps=$3; shift 3
for r in $(seq "$reps"); do
  for b in "$@"; do
    LD_LIBRARY_PATH=/tmp/lib_$b OMP_WAIT_POLICY=passive /tmp/drape_sim_$b "$scene" --out /tmp/ab_$b --threads "$t" >/dev/null 2>&1
    awk -v b="$b" '/^steps:/{s=$2} /^rejected_steps:/{rj=$2} /collision_ms_per_step/{c=$2} /assembly_ms_per_step/{a=$2}
      /proximity_total/{p=$2} /broad_phase/{bp=$2} /crossing_detect/{cd=$2} /wall_time/{w=$2}
      END {printf "%-6s steps %d rej %d wall %.2f coll %.3f (broad %.3f prox %.3f cross %.3f) asm %.3f ratio %.3f\n",
           b, s, rj, w, c, bp, p, cd, a, c/a}' /tmp/ab_$b/result.yaml
  done
done
