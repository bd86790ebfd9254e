#!/bin/bash
# Cost per step of the 62.5k yarn sheet before (a2ce2fd) and after (dff8f1a) the solvers' compact copy
# of the system, the single angle evaluation per crossing pair and the yarn model's remaining serial
# loops on all threads (README.md): two yarn_step_bench binaries alternating in one session.
#   OLD=<yarn_step_bench of a2ce2fd> NEW=<yarn_step_bench of dff8f1a> bash run.sh [ROUNDS] [FIRST] [WHICH]
# ROUNDS rounds numbered from FIRST (default 1); WHICH = both (default) or semi_implicit.
# The same rounds as ../2026-12-07-yarn-compact-product/run.sh, written here.
set -eu
here=$(cd "$(dirname "$0")" && pwd)
OUT_DIR=$here exec bash "$here/../2026-12-07-yarn-compact-product/run.sh" "$@"
