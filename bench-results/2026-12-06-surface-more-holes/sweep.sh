source /tmp/env.sh
B=$1; OUT=$2; M=$3; shift 3
for S in 1 2 3 4 5 6 7 8 9 10 11 12 13 14 strided; do
  if [ $S = strided ]; then A="--sampling strided --seed 1"; else A="--seed $S"; fi
  python3 jobs/bench/surface.py $OUT/$S $A --methods $M --time-runs 1 --binary $B "$@" > $OUT/$S.log 2>&1
done
echo done > $OUT/DONE
