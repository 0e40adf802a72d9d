#!/usr/bin/env bash
# Sets up a fresh machine (jobs/setup.sh) and runs the whole test suite: unit and property tests,
# distributed-vs-serial runs of the real binary under mpirun -n 1, 2 and 3, reconstruction quality
# on the bunny, the VTKHDF read-back through VTK's own reader; then rustdoc with warnings as errors.
set -euo pipefail
cd "$(dirname "$0")/.."
source jobs/setup.sh
export OMPI_MCA_rmaps_base_oversubscribe=1   # the 3-rank tests run on 2 cores
export RAYON_NUM_THREADS=${RAYON_NUM_THREADS:-1}
cargo test --release "$@"
# the internal docs build without broken links, and the API documentation (left in target/doc)
# without broken or private ones
RUSTDOCFLAGS="-D warnings" cargo doc --no-deps --document-private-items --quiet
RUSTDOCFLAGS="-D warnings" cargo doc --no-deps --quiet
