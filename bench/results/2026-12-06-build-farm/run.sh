#!/bin/bash
# The build-farm benchmark of docs/build_farm.md: farm_bench on a throw-away PostgreSQL server and SQLite
# files, 1, 2 and 4 MPI ranks, 3 interleaved rounds, the 30 cm square at d = 3 cm on the 6x6 quadrant grid
# (36 simulations per build). The planning table takes its cost per simulation from COST_DB, a towel
# database at the production spacing (the replay tests' database, d = 2/3 cm, built by catkin_make tests).
# usage: run.sh OUT_DIR [COST_DB]   (from a built workspace: .build/ws/devel/lib/textile_handling)
set -euo pipefail
OUT=${1:?usage: run.sh OUT_DIR}
REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/../../.." && pwd)"
BIN="$REPO/.build/ws/devel/lib/textile_handling"
export OMP_WAIT_POLICY=passive
PG_DIR=$(mktemp -d /tmp/th_farm_bench_pg.XXXXXX)
trap 'bash "$REPO/scripts/throwaway_postgres.sh" stop "$PG_DIR" >/dev/null 2>&1 || true; rm -rf "$PG_DIR"' EXIT
URL=$(bash "$REPO/scripts/throwaway_postgres.sh" start "$PG_DIR")
mkdir -p "$OUT"
"$BIN/farm_bench" --out "$OUT" --drape-db "$BIN/drape_db" --mpirun "$(command -v mpirun)" --postgres "$URL" \
  --ranks 1,2,4 --rounds 3 --textile square --spacing 0.03 --grid 6x6 --load-repeats 5 \
  ${2:+--cost-db "$2"} | tee "$OUT/farm_bench.txt"
