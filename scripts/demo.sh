#!/usr/bin/env bash
# The main job: installs dependencies, builds, and runs the drape simulation demo — the thesis's
# 64x46 cm cotton towel held at a corner, simulated from the released flat sheet to rest.
# Writes out/demo/{result.yaml, rest_positions.csv, rest_shape.png, state.txt}.
# Usage: bash scripts/demo.sh [SCENE.yaml]
set -euo pipefail
REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$REPO/scripts/setup.sh"
SCENE="${1:-$REPO/config/scenes/towel_corner.yaml}"
OUT="$REPO/out/demo"
"$REPO/.build/ws/devel/lib/textile_handling/drape_sim" "$SCENE" --out "$OUT"
