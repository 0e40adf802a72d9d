# The openx sets of the fifteen samplings with the quadric caps (cap.py), from the repository root:
#   CAP=collar=6,resid=0.12 bash bench-results/2026-12-07-surface-quadric-caps/sweep.sh BINARY OUT
B=$1; OUT=$2
for S in 1 2 3 4 5 6 7 8 9 10 11 12 13 14 strided; do
  if [ $S = strided ]; then A="--sampling strided --seed 1"; else A="--seed $S"; fi
  python3 bench-results/2026-12-07-surface-quadric-caps/cap.py $OUT/$S $A --methods default --time-runs 1 \
    --binary $B --variants openx > $OUT/$S.log 2>&1
done
# then: python3 jobs/bench/surface_holes.py OUT bench-results/2026-12-06-surface-second-hole/baseline \
#   bench-results/2026-12-06-surface-default-carrier/p03-openx
