#!/usr/bin/env bash
# The main job: installs dependencies, builds, and runs the cell demo end to end:
#  1. creates the default drape database on first run (embedded SQLite at out/demo/drapes.sqlite: the
#     thesis's 64x46 cm cotton towel, 36 hold points in one quadrant at d = 2/3 cm, 36 views each; the
#     rest are mirrored), with a progress bar (about 17 minutes on a 2-core machine, measured 2026-12-03) — an interrupted build
#     resumes on the next run;
#  2. replays the bundled bag (test/data/towel_replay_a.bag: the towel hanging from a gripper in front
#     of the cell camera, simulated independently at d = 0.5 cm and held at a point that is not a
#     database hold point) with simulated time;
#  3. prints the recognised textile, hold point and grasp poses (and, for a bag with a .truth.yaml next to
#     it, how far the grasp poses are from the ground truth).
# Usage: bash scripts/demo.sh [BAG]
set -euo pipefail
REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$REPO/scripts/setup.sh"
BAG="${1:-$REPO/test/data/towel_replay_a.bag}"
OUT="$REPO/out/demo"
DB="$OUT/drapes.sqlite"
mkdir -p "$OUT"
BIN="$REPO/.build/ws/devel/lib/textile_handling"
# shellcheck disable=SC1091
set +u; source "$REPO/.build/ws/devel/setup.bash"; set -u
echo "[demo] database $DB"
# Builds what is missing (nothing when complete): the thesis's 6x6 quadrant grid of hold points, at the
# resolution the recognizer needs for grasp frames within a few cm (docs/recognition.md). Linear solves
# to 1e-3 with warm starts: about half the build time of the builder's tight default, at the cost of a
# few rest shapes in neighbouring equilibria (docs/database.md, "Build speed").
OMP_WAIT_POLICY=passive "$BIN/drape_db" build --db "$DB" --textile towel --grid 6x6 --spacing 0.006666666666666667 \
  --cg-tolerance 0.001 --cg-warm-start
"$BIN/drape_db" list --db "$DB"
echo "[demo] replaying $BAG"
set +e
TRUTH=""
[ -f "$BAG.truth.yaml" ] && TRUTH="$BAG.truth.yaml"
roslaunch textile_handling demo.launch bag:="$BAG" database_path:="$DB" truth:="$TRUTH" > "$OUT/replay.log" 2>&1 &
LAUNCH=$!
# (rosbag's progress line shares terminal lines with the printout: split at carriage returns)
tail -n +1 -f "$OUT/replay.log" --pid=$LAUNCH | stdbuf -o0 tr '\r' '\n' |
  grep --line-buffered -E "\[recognition\]|^    [a-z]|FATAL|\[ERROR\]" | sed -u 's/^.*\[recognition\]/[recognition]/'
wait $LAUNCH
set -e
if grep -q "\[recognition\] frame .* held at" "$OUT/replay.log"; then
  echo "[demo] done; full log in $OUT/replay.log"
else
  echo "[demo] no recognition result; see $OUT/replay.log" >&2
  exit 1
fi
