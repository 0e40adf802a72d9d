#!/usr/bin/env bash
# Installs what volspline needs on a fresh Debian 12 machine: OpenMPI, parallel HDF5 (OpenMPI
# flavour), MUMPS (libmumps-dev: the OpenMPI build, with ScaLAPACK for OpenMPI), libclang and
# pkg-config for the -sys crates and build.rs, hdf5-tools, bsdutils (script(1), with which a test
# gives the binary a terminal), and the Python packages the tests use (vtk, numpy, pye57).
# Idempotent and quiet when everything is present. A shell that sources it keeps its own options (errexit,
# nounset, pipefail) afterwards; the jobs set theirs before sourcing it.
_volspline_caller_opts=$(set +o)
# (a command substitution does not see errexit: take it from $-)
case $- in *e*) _volspline_caller_opts+=$'\nset -e' ;; esac
set -euo pipefail

# ensure_debs PKG...: installs the Debian packages that are missing, quietly
ensure_debs() {
    local need=() pkg
    for pkg in "$@"; do
        dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed" || need+=("$pkg")
    done
    if [ ${#need[@]} -gt 0 ]; then
        echo "setup: installing ${need[*]}"
        local sudo=""; [ "$(id -u)" -eq 0 ] || sudo="sudo"
        $sudo apt-get update -qq
        DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${need[@]}" >/dev/null
    fi
}
ensure_debs libopenmpi-dev openmpi-bin libhdf5-openmpi-dev libclang-dev pkg-config hdf5-tools libmumps-dev bsdutils libopenblas0-serial

# two MPI flavours in one build make binaries abort at start ("Invalid communicator")
if dpkg-query -W -f='${Status}' libmpich-dev 2>/dev/null | grep -q "install ok installed"; then
    echo "setup: warning: libmpich-dev is installed next to OpenMPI; volspline builds against OpenMPI" >&2
fi

if [ "${VOLSPLINE_SKIP_PYTHON:-0}" != 1 ]; then
    PY=${PYTHON:-python3}
    if ! "$PY" -c 'import vtk, numpy, pye57' 2>/dev/null; then
        echo "setup: installing Python packages vtk, numpy, pye57"
        "$PY" -m pip install -q --disable-pip-version-check vtk numpy pye57
    fi
fi

# mpirun refuses to run as root without these; harmless otherwise
if [ "$(id -u)" -eq 0 ]; then
    export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
fi

eval "$_volspline_caller_opts"
unset _volspline_caller_opts
