#!/bin/bash
# PostgreSQL farm builds of two drape_db binaries (two commits, each built in its own workspace so that it
# loads its own libraries), interleaved: per round, for each binary in a rotated order, 1 and 2 ranks of
# `mpirun -np R drape_db build --mpi` of the 30 cm square at d = 3 cm on the 6x6 quadrant grid into a fresh
# schema of one throw-away server. Writes OUT/compare.csv (whole wall and the build's own wall and summed
# simulation time, from its summary line) and the CPU time the server spent on the build (the postmaster's
# own and its reaped backends' user + system time).
# usage: compare_commits.sh OLD_DRAPE_DB NEW_DRAPE_DB OUT_DIR [ROUNDS=4]
set -euo pipefail
OLD=${1:?usage}; NEW=${2:?usage}; OUT=${3:?usage}; ROUNDS=${4:-4}
REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/../../.." && pwd)"
export OMP_WAIT_POLICY=passive
PG_DIR=$(mktemp -d /tmp/th_farm_cmp_pg.XXXXXX)
trap 'bash "$REPO/scripts/throwaway_postgres.sh" stop "$PG_DIR" >/dev/null 2>&1 || true; rm -rf "$PG_DIR"' EXIT
URL=$(bash "$REPO/scripts/throwaway_postgres.sh" start "$PG_DIR")
mkdir -p "$OUT"
echo "round,binary,ranks,wall_s,build_wall_s,simulation_s,server_cpu_s" > "$OUT/compare.csv"
PM=$(head -1 "$PG_DIR/data/postmaster.pid")
TICK=$(getconf CLK_TCK)
# The server's CPU seconds so far: utime + stime + cutime + cstime of the postmaster (fields 14-17).
server_cpu() { awk -v t="$TICK" '{ sub(/^.*\) /, ""); print ($12 + $13 + $14 + $15) / t }' "/proc/$PM/stat"; }
ROOT=(); [ "$(id -u)" = 0 ] && ROOT=(--allow-run-as-root)
for round in $(seq 1 "$ROUNDS"); do
  order=(old new); [ $((round % 2)) = 0 ] && order=(new old)
  for which in "${order[@]}"; do
    exe=$OLD; [ "$which" = new ] && exe=$NEW
    for ranks in 1 2; do
      schema="cmp_${which}_${round}_${ranks}"
      psql -q "$URL" -c "DROP SCHEMA IF EXISTS $schema CASCADE; CREATE SCHEMA $schema"
      db="$URL?options=-csearch_path%3D$schema"
      c0=$(server_cpu)
      t0=$(date +%s.%N)
      mpirun --oversubscribe -np "$ranks" "${ROOT[@]}" "$exe" build --mpi --db "$db" --textile square \
        --spacing 0.03 --grid 6x6 --quiet > "$OUT/${schema}.log" 2>&1
      t1=$(date +%s.%N)
      sleep 0.5  # let the postmaster reap the backends
      c1=$(server_cpu)
      line=$(grep "this build" "$OUT/${schema}.log")
      bw=$(sed -E 's/.*; ([0-9.]+) s wall.*/\1/' <<< "$line")
      st=$(sed -E 's/.* s wall, ([0-9.]+) s simulation time.*/\1/' <<< "$line")
      w=$(echo "$t1 - $t0" | bc)
      echo "$round,$which,$ranks,$w,$bw,$st,$(echo "$c1 - $c0" | bc)" | tee -a "$OUT/compare.csv"
    done
  done
done
