#!/usr/bin/env bash
# The README's picture of reconstruction from contours: the cow cut by `volspline slice` into 30
# parallel slices and rebuilt by `volspline contours` (four legs branching into one body, no
# correspondence given), and a bent and twisted block from 50 non-parallel sections (the case of
# Figure 4 of Savchenko et al. 1995). Writes bench-results/contours-figure/{contours.png,command.txt}.
# Needs matplotlib and numpy (pip install matplotlib). Set VOLSPLINE to use another binary.
set -euo pipefail
cd "$(dirname "$0")/.."
if [ -z "${VOLSPLINE:-}" ]; then
    source jobs/setup.sh
    cargo build --release --quiet
    VOLSPLINE=target/release/volspline
fi
DEST=bench-results/contours-figure
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
mkdir -p "$DEST"
RUN=(mpirun -n "${RANKS:-2}" --oversubscribe)
"${RUN[@]}" "$VOLSPLINE" slice tests/data/cow.obj --out "$WORK/cow.txt" --planes y:30
"${RUN[@]}" "$VOLSPLINE" contours "$WORK/cow.txt" --out "$WORK/cow" --carrier union --grid 96
python3 jobs/render_contours.py block-sections "$WORK/block.txt"
"${RUN[@]}" "$VOLSPLINE" contours "$WORK/block.txt" --out "$WORK/block" --grid 96
python3 jobs/render_contours.py render "$DEST/contours.png" \
    "$WORK/cow.ply" "$WORK/cow.txt" y "cow: 30 parallel slices (union carrier)" \
    "$WORK/block.ply" "$WORK/block.txt" z "bent, twisted block: 50 non-parallel sections"
{
    echo "# $(date -u +%Y-%m-%dT%H:%M:%SZ), git $(git rev-parse --short HEAD 2>/dev/null || echo unknown)"
    echo "volspline slice tests/data/cow.obj --out cow.txt --planes y:30"
    echo "volspline contours cow.txt --out cow --carrier union --grid 96"
    echo "python3 jobs/render_contours.py block-sections block.txt"
    echo "volspline contours block.txt --out block --grid 96"
    echo "python3 jobs/render_contours.py render contours.png cow.ply cow.txt ... block.ply block.txt ..."
} > "$DEST/command.txt"
echo "wrote $DEST/contours.png"
