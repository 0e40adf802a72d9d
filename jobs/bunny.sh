#!/usr/bin/env bash
# The main job: sets up a fresh machine, builds volspline and reconstructs the Stanford bunny from
# its 5051 vertices on 2 MPI ranks. Outputs go to target/out/bunny.{model.h5,hdf,ply} (override with
# OUT=prefix); open target/out/bunny.hdf in ParaView and contour f at 0.
set -euo pipefail
cd "$(dirname "$0")/.."
source jobs/setup.sh
cargo build --release --quiet
OUT=${OUT:-target/out/bunny}
mkdir -p "$(dirname "$OUT")"
mpirun -n "${RANKS:-2}" target/release/volspline fit tests/data/bunny10k.obj --out "$OUT" "$@"
