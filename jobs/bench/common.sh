# Shared set-up of the benchmark jobs (sourced): machine set-up, release build, a dated result
# folder with the exact command, git revision and machine description.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
cd "$ROOT"
if [ -n "${VOLSPLINE_PREBUILT:-}" ]; then
    # a node without compilers or Debian packages: the programs come from a bundle made by
    # jobs/bundle (its env.sh sets VOLSPLINE_PREBUILT, PATH and the libraries)
    BIN="$VOLSPLINE_PREBUILT/volspline"
    [ -x "$BIN" ] || { echo "bench: no volspline in VOLSPLINE_PREBUILT=$VOLSPLINE_PREBUILT" >&2; exit 2; }
else
    source jobs/setup.sh
    # peers measured side by side: ScaLAPACK over OpenBLAS (serial, one thread per rank), scipy
    ensure_debs libscalapack-openmpi-dev libopenblas0-serial
    python3 -c 'import scipy, matplotlib' 2>/dev/null || python3 -m pip install -q --disable-pip-version-check scipy matplotlib
    cargo build --release --quiet
    BIN="$ROOT/target/release/volspline"
fi

# tool NAME DEST: the helper program NAME (scalapack, micro_blas, micro_mpi, gemm_rate) at DEST,
# built here from jobs/bench/, or copied from the bundle on a node without compilers
tool() {
    if [ -n "${VOLSPLINE_PREBUILT:-}" ]; then
        cp "$VOLSPLINE_PREBUILT/$1" "$2"
        return
    fi
    case $1 in
        scalapack) mpicc -O2 jobs/bench/scalapack_driver.c -o "$2" -lscalapack-openmpi ;;
        micro_blas) gcc -O2 jobs/bench/micro_blas.c -o "$2" -l:liblapack.so.3 -l:libblas.so.3 ;;
        micro_mpi) mpicc -O2 jobs/bench/micro_mpi.c -o "$2" ;;
        gemm_rate) cargo build --release --quiet --example gemm_rate && cp "$ROOT/target/release/examples/gemm_rate" "$2" ;;
        *) echo "bench: unknown tool $1" >&2; exit 2 ;;
    esac
}
export OMPI_MCA_rmaps_base_oversubscribe=1

# OpenBLAS (ScaLAPACK's and the micro-benchmarks' BLAS) picks its kernels by processor model. A
# processor newer than the OpenBLAS release (a recent Xeon under Debian 12's 0.3.21) gets generic
# SSE kernels at a fifth of the rate, and a recent AMD processor gets the AVX2 (Haswell) kernels
# at 60 % of the AVX-512 rate; some machines also set OPENBLAS_CORETYPE=Haswell in their
# environment. Either would make every peer look slow. Where the processor has AVX-512 and the
# kernels in effect have none (chosen by OpenBLAS or set in the environment), its Skylake-X
# kernels are taken; BENCH_OPENBLAS_CORETYPE=NAME takes NAME instead, whatever the processor. The
# core in use goes into machine.txt.
openblas_core() {
    python3 -c "import ctypes; l = ctypes.CDLL('libopenblas.so.0'); l.openblas_get_corename.restype = ctypes.c_char_p; print(l.openblas_get_corename().decode())" 2>/dev/null || echo unknown
}
OPENBLAS_CORE=$(openblas_core)
if [ -n "${BENCH_OPENBLAS_CORETYPE:-}" ]; then
    export OPENBLAS_CORETYPE=$BENCH_OPENBLAS_CORETYPE
    OPENBLAS_CORE="$(openblas_core) (BENCH_OPENBLAS_CORETYPE=$BENCH_OPENBLAS_CORETYPE)"
elif grep -qw avx512f /proc/cpuinfo; then
    case ${OPENBLAS_CORE,,} in
        skylakex|cooperlake|sapphirerapids|unknown) ;;
        *) chosen="OpenBLAS chose $OPENBLAS_CORE"
           [ -n "${OPENBLAS_CORETYPE:-}" ] && chosen="the environment set OPENBLAS_CORETYPE=$OPENBLAS_CORETYPE"
           echo "bench: $chosen on an AVX-512 processor; taking SkylakeX" >&2
           export OPENBLAS_CORETYPE=SkylakeX
           OPENBLAS_CORE="$(openblas_core) (forced: $chosen)" ;;
    esac
fi

# bench_dir NAME ARGS...: creates bench-results/DATE-NAME/ (DATE-$BENCH_NAME where BENCH_NAME is
# set, so that a second run of a day keeps the first) and records the command and machine
bench_dir() {
    local name=${BENCH_NAME:-$1}; shift
    OUT="$ROOT/bench-results/$(date -u +%Y-%m-%d)-$name"
    # results already committed are never overwritten (a job's default name may repeat that of a
    # run earlier the same day)
    if [ -d "$OUT" ] && [ -n "$(git -C "$ROOT" ls-files -- "$OUT" 2>/dev/null)" ]; then
        echo "bench: $OUT holds committed results; name this run otherwise (BENCH_NAME or the job's own *_BENCH_NAME)" >&2
        exit 2
    fi
    mkdir -p "$OUT"
    printf '%s\n' "$*" > "$OUT/command.txt"
    {
        echo "date_utc: $(date -u +%Y-%m-%dT%H:%M:%SZ)"
        if [ -n "${VOLSPLINE_PREBUILT:-}" ]; then
            echo "bundle: $VOLSPLINE_PREBUILT (programs and runtime built elsewhere, below)"
            sed 's/^/bundle_/' "$VOLSPLINE_PREBUILT/../MANIFEST"
            echo "host: $(. /etc/os-release; echo "$PRETTY_NAME"), $(ldd --version | head -1)"
        else
            echo "git_revision: $(git -C "$ROOT" rev-parse HEAD)$(git -C "$ROOT" diff --quiet || echo ' (with uncommitted changes)')"
        fi
        echo "cpu: $(lscpu | sed -n 's/^Model name: *//p')"
        echo "cores: $(nproc)"
        echo "flags: $(grep -o -w -E 'avx2|avx512f|fma' /proc/cpuinfo | sort -u | tr '\n' ' ')"
        echo "memory: $(free -g | awk '/Mem:/{print $2}') GiB"
        echo "kernel: $(uname -r)"
        echo "mpi: $(mpirun --version 2>&1 | head -1)"
        echo "hdf5: $(dpkg-query -W -f='${Package} ${Version}' libhdf5-openmpi-dev 2>/dev/null)"
        echo "openblas_core: $OPENBLAS_CORE"
        echo "scalapack: $(dpkg-query -W -f='${Package} ${Version}' libscalapack-openmpi-dev 2>/dev/null) over $(readlink -f /usr/lib/x86_64-linux-gnu/libblas.so.3)"
        echo "python: $(python3 --version 2>&1), numpy $(python3 -c 'import numpy; print(numpy.__version__)'), scipy $(python3 -c 'import scipy; print(scipy.__version__)')"
        echo "rustc: $(rustc --version)"
        echo "load_average_at_start: $(cut -d' ' -f1-3 /proc/loadavg)"
    } > "$OUT/machine.txt"
    echo "bench: results in $OUT"
}

bench_done() {
    echo "load_average_at_end: $(cut -d' ' -f1-3 /proc/loadavg)" >> "$OUT/machine.txt"
}
