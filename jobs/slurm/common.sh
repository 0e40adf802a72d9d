# Shared part of the Slurm jobs (sourced from a batch script, inside the allocation): builds
# volspline if needed and opens a result folder recording the job, the nodes and the software.
set -euo pipefail
cd "${SLURM_SUBMIT_DIR:?run these scripts with sbatch}"
ROOT=$PWD
if [ ! -x target/release/volspline ]; then
    cargo build --release --quiet
fi
BIN="$ROOT/target/release/volspline"
THREADS=${SLURM_CPUS_PER_TASK:-1}
export RAYON_NUM_THREADS=$THREADS OMP_NUM_THREADS=$THREADS OPENBLAS_NUM_THREADS=$THREADS

# the rank counts of a strong-scaling study: 1, 2, 4, ... up to the allocation, and the
# allocation itself (override with RANKS="...")
default_ranks() {
    local p=1 list=""
    while [ "$p" -lt "$SLURM_NTASKS" ]; do list="$list $p"; p=$((p * 2)); done
    echo "$list $SLURM_NTASKS"
}

bench_dir() {
    local name=$1; shift
    OUT="$ROOT/bench-results/$(date -u +%Y-%m-%d)-slurm-$name-${SLURM_JOB_ID}"
    mkdir -p "$OUT"
    printf '%s\n' "$*" > "$OUT/command.txt"
    {
        echo "date_utc: $(date -u +%Y-%m-%dT%H:%M:%SZ)"
        echo "git_revision: $(git rev-parse HEAD)"
        echo "slurm_job: $SLURM_JOB_ID on $SLURM_JOB_NUM_NODES nodes ($SLURM_JOB_NODELIST), $SLURM_NTASKS tasks, $THREADS cpus per task"
        echo "cpu: $(lscpu | sed -n 's/^Model name: *//p')"
        echo "cores: $(nproc --all) per node"
        echo "memory: $(free -g | awk '/Mem:/{print $2}') GiB per node"
        echo "mpi: $(mpirun --version 2>&1 | head -1)"
        echo "rustc: $(rustc --version 2>/dev/null || echo unknown)"
    } > "$OUT/machine.txt"
    echo "results in $OUT"
}
