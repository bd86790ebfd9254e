#!/bin/bash
for t in 2 1; do
  for sc in side corner; do f=scenes/towel_side.yaml; [ $sc = corner ] && f=../../../config/scenes/towel_corner.yaml
    echo "== $sc threads $t"; ./ab.sh $f $t 3 s4 final; done
  for h in hold_0201 hold_0503 hold_033045 hold_064023; do echo "== $h threads $t"; ./ab.sh scenes/towel_$h.yaml $t 2 s4 final; done
done
