#!/usr/bin/env bash
# Regenerates the bundled test data (run after a change to the database schema, the simulator or the
# renderers; the files are committed):
#   test/data/towel_test.sqlite   drape database: thesis towel, 6x6 quadrant grid of hold points
#                                 (121 with mirrors), d = 2 cm, 36 views (the demo's database)
#   test/data/towel_replay_{a,b}.bag (+ .truth.yaml)
#                                 the towel held at held-out points (config/scenes/replay_{a,b}.yaml,
#                                 d = 1.5 cm), gripper turned to 25 and 155 deg (views between the
#                                 stored ones), 320x240 camera, 2 frames per view, bz2-compressed
# Usage: bash scripts/make_test_data.sh
set -euo pipefail
REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BIN="$REPO/.build/ws/devel/lib/textile_handling"
DATA="$REPO/test/data"
mkdir -p "$DATA"
rm -f "$DATA/towel_test.sqlite"
"$BIN/drape_db" build --db "$DATA/towel_test.sqlite" --textile towel --grid 6x6 --spacing 0.02 --threads 2 --quiet
for n in a b; do
  "$BIN/record_drape_bag" "$REPO/config/scenes/replay_$n.yaml" --out "$DATA/towel_replay_$n.bag" \
    --yaw 25,155 --frames-per-view 2 --period 1.0 --width 320 --compress --seed 7 --depth
done
ls -la "$DATA"
