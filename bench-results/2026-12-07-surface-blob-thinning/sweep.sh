source jobs/setup.sh; export RAYON_NUM_THREADS=1 OMPI_MCA_rmaps_base_oversubscribe=1
B=$1; OUT=$2; shift 2; mkdir -p $OUT
SEEDS=${SEEDS:-"1 2 3 4 5 6 7 8 9 10 11 12 13 14 strided"}
for S in $SEEDS; do
  if [ $S = strided ]; then A="--sampling strided --seed 1"; else A="--seed $S"; fi
  python3 jobs/bench/surface.py $OUT/$S $A --methods default --time-runs 1 --binary $B "$@" > $OUT/$S.log 2>&1
done
echo done > $OUT/DONE
