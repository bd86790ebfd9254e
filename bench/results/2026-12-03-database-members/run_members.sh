#!/bin/bash
# Builds the members one at a time into /tmp/mem/m.sqlite, snapshotting after each: m_k.sqlite = base + first k-1 members.
set -e
B=/work/main/.build/ws/devel/lib/textile_handling/drape_db
cd /tmp/mem
k=1
for m in base heap tilted soft_light stiff_heavy heap_b self_collision; do
  s=$(date +%s)
  OMP_WAIT_POLICY=passive $B build --db /tmp/mem/m.sqlite --textile towel --grid 6x6 --spacing 0.01 --cg-tolerance 0.001 --cg-warm-start --quiet --members $m > /tmp/mem/build_$m.log 2>&1 || echo "member $m exit $?" >> /tmp/mem/status.log
  e=$(date +%s)
  echo "$k $m $((e-s)) s" >> /tmp/mem/status.log
  cp /tmp/mem/m.sqlite /tmp/mem/m_$k.sqlite
  k=$((k+1))
done
echo done >> /tmp/mem/status.log
