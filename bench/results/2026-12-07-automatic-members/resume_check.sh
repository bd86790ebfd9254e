#!/usr/bin/env bash
# After run.sh's builds (same $WORK): the automatic build run again on a copy of its database. Its search must
# repeat the choice (the members rule decides on work counts, not times) and find every row done.
set -u
D=.build/ws/devel/lib/textile_handling
OUT=bench/results/2026-12-07-automatic-members
WORK=${WORK:-/tmp/am}
export OMP_WAIT_POLICY=passive OMP_NUM_THREADS=1
cp "$WORK/auto.sqlite" "$WORK/auto_resume.sqlite"
$D/drape_db build --db "$WORK/auto_resume.sqlite" --auto --textile towel --grid 6x6 --cg-tolerance 0.001 --cg-warm-start \
  --threads 1 --sim-threads 1 --quiet > "$OUT/resume_check.log" 2>&1
grep -v "s of search" "$OUT/auto_build.log" | grep -E "^(model|members|evidence)" > "$WORK/choice_first.txt"
grep -v "s of search" "$OUT/resume_check.log" | grep -E "^(model|members|evidence)" > "$WORK/choice_again.txt"
if cmp -s "$WORK/choice_first.txt" "$WORK/choice_again.txt"; then echo "same choice and evidence"; else echo "choice differs"; fi \
  >> "$OUT/resume_check.log"
