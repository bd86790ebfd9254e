#!/usr/bin/env bash
# Regenerates the bundled test bags (run after a change to the simulator or the renderers; the files are
# committed):
#   test/data/towel_replay_{a,b}.bag (+ .truth.yaml)
#       the thesis towel held at held-out points (config/scenes/replay_{a,b}.yaml: near a corner and near
#       the middle of a short side, 1.1-1.3 cm from the database's lattice points), simulated at
#       d = 0.5 cm, gripper turned to 25 and 155 deg (views between the stored ones), 320x240 camera with
#       depth, 2 frames per view, bz2-compressed.
# The replay tests' database (towel, 6x6 quadrant grid, d = 2/3 cm) is not committed: the build makes it
# (CMake target th_replay_test_database; docs/recognition.md).
# Usage: bash scripts/make_test_data.sh
set -euo pipefail
REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BIN="$REPO/.build/ws/devel/lib/textile_handling"
DATA="$REPO/test/data"
mkdir -p "$DATA"
for n in a b; do
  OMP_WAIT_POLICY=passive "$BIN/record_drape_bag" "$REPO/config/scenes/replay_$n.yaml" --out "$DATA/towel_replay_$n.bag" \
    --yaw 25,155 --frames-per-view 2 --period 1.0 --width 320 --compress --seed 7 --depth
done
ls -la "$DATA"
