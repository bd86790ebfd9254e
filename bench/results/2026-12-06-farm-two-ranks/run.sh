#!/bin/bash
# Two-rank build-farm efficiency on both backends, more rounds than the first farm benchmark
# (../2026-12-06-build-farm): farm_bench on a throw-away PostgreSQL server and SQLite files, 1 and 2 MPI
# ranks, 6 interleaved rounds, the 30 cm square at d = 3 cm on the 6x6 quadrant grid (36 simulations).
# usage: run.sh OUT_DIR   (from a built workspace: .build/ws/devel/lib/textile_handling)
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
  --ranks 1,2 --rounds 6 --textile square --spacing 0.03 --grid 6x6 --load-repeats 5 | tee "$OUT/farm_bench.txt"
