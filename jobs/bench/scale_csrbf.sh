# The body of the csrbf scaling study, sourced by jobs/scale-csrbf (mpirun) and
# jobs/slurm/scale-csrbf.sbatch (srun) after they set ROOT, BIN, OUT, TMP and
#   launch P CMD...   run CMD on P ranks
# and the study's variables: SIZES, RANKS, GRID, HELD, SEED, THREADS, MAX_SECONDS, METHOD_ARGS,
# FERREUS, FERREUS_THREADS, FERREUS_GRID (see jobs/scale-csrbf). Grids have GRID nodes on every
# side of the box (GRID^3 nodes, cells not cubic), FERREUS_GRID^3 for the peer.
# For every N in SIZES: N points sampled uniformly on tests/data/bunny10k.obj and HELD held-out
# samples (the same for every N); volspline fits on each rank count of RANKS (stage times, peak
# memory, nonzeros, fill, the GRID^3 evaluation inside the fit) and the distance of the held-out
# samples to the reconstructed surface; ferreus_rbf on the same points; one raw.csv row per run.
# A run whose predicted wall time (jobs/bench/predict.py) exceeds MAX_SECONDS is skipped
# (skipped.txt), a failed run is recorded (failed.txt) and ends that series.
MESH="$ROOT/tests/data/bunny10k.obj"
if [ "$FERREUS" = 1 ] && ! python3 -c 'import ferreus_rbf' 2>/dev/null; then
    python3 -m pip install -q --disable-pip-version-check ferreus-rbf==0.3.0 \
        || { echo "scale-csrbf: ferreus-rbf could not be installed; running without the peer" >&2; FERREUS=0; }
fi
[ "$FERREUS" = 1 ] && echo "ferreus_rbf: $(python3 -c 'from importlib.metadata import version; print(version("ferreus-rbf"))')" >> "$OUT/machine.txt"
HEADER="impl,points,ranks,threads,kernel,support,leaf,sparse_solver,tree_nodes,tree_levels,nnz_row_mean,nnz_row_max,stored_entries,fill,read_s,tree_s,assemble_s,factor_s,solve_s,check_s,evaluate_s,mesh_s,write_s,fit_s,wall_s,grid_nodes,triangles,peak_rss_bytes,rms_at_points,max_at_points,residual,dist_mean_pct,dist_p95_pct,dist_max_pct"
echo "$HEADER" > "$OUT/raw.csv"
: > "$OUT/skipped.txt"
: > "$OUT/failed.txt"
kv() { awk -F, -v k="$2" '$1==k{print $2}' "$1"; }
now() { date +%s.%N; }
since() { awk -v a="$1" -v b="$(now)" 'BEGIN{printf "%.3f", b - a}'; }
# stage_X_max_s of the fit stages (up to the solution; not check, evaluate, mesh, write)
fit_seconds() { awk -F, '$1~/^stage_(read|tree|assemble|factor|solve)_max_s$/{s+=$2} END{printf "%.6f", s}' "$1"; }
# guard IMPL RANKS N: true when the run fits the time budget; otherwise notes the skip
guard() {
    local pred
    if grep -q "^$1 ranks=$2 " "$OUT/failed.txt"; then
        echo "$1 ranks=$2 N=$3: skipped, a smaller run of this series failed" >> "$OUT/skipped.txt"
        return 1
    fi
    pred=$(python3 "$ROOT/jobs/bench/predict.py" "$OUT/raw.csv" "$1" "$2" "$3")
    if awk -v p="$pred" -v m="$MAX_SECONDS" 'BEGIN{exit !(p > m)}'; then
        echo "$1 ranks=$2 N=$3: skipped, predicted ${pred} s > MAX_SECONDS=$MAX_SECONDS" >> "$OUT/skipped.txt"
        echo "  $1 ranks=$2 N=$3: skipped (predicted ${pred} s)"
        return 1
    fi
}
for n in $SIZES; do
    python3 "$ROOT/jobs/bench/sample_surface.py" "$MESH" "$n" "$TMP/p.xyz" --seed "$SEED" --held-out "$HELD" "$TMP/held.xyz"
    for p in $RANKS; do
        guard volspline "$p" "$n" || continue
        rm -f "$TMP/t.csv" "$TMP/o.ply" "$TMP/d.csv"
        t0=$(now)
        if ! launch "$p" "$BIN" fit "$TMP/p.xyz" --out "$TMP/o" --surface carrier $METHOD_ARGS --grid "$GRID,$GRID,$GRID" \
            --threads "$THREADS" --timings "$TMP/t.csv" > "$TMP/log" 2>&1; then
            echo "volspline ranks=$p N=$n failed:" >> "$OUT/failed.txt"
            tail -20 "$TMP/log" | sed 's/^/    /' >> "$OUT/failed.txt"
            echo "  volspline ranks=$p N=$n: FAILED (see failed.txt)"
            continue
        fi
        wall=$(since "$t0")
        python3 "$ROOT/jobs/bench/distance.py" "$TMP/o.ply" "$TMP/held.xyz" > "$TMP/d.csv"
        g() { kv "$TMP/t.csv" "$1"; }
        s() { kv "$TMP/t.csv" "stage_$1_max_s"; }
        echo "volspline,$(g points),$p,$(g threads),$(g kernel),$(g support),$(g leaf),$(g sparse_solver),$(g tree_nodes),$(g tree_levels),$(g nnz_row_mean),$(g nnz_row_max),$(g stored_entries),$(g fill),$(s read),$(s tree),$(s assemble),$(s factor),$(s solve),$(s check),$(s evaluate),$(s mesh),$(s write),$(fit_seconds "$TMP/t.csv"),$wall,$(g grid_nodes),$(g triangles),$(g peak_rss_bytes_max),$(g rms_at_points),$(g max_at_points),$(g residual),$(kv "$TMP/d.csv" dist_mean_pct),$(kv "$TMP/d.csv" dist_p95_pct),$(kv "$TMP/d.csv" dist_max_pct)" >> "$OUT/raw.csv"
        echo "  volspline N=$n ranks=$p: fit $(fit_seconds "$TMP/t.csv") s, evaluate $(s evaluate) s, wall $wall s, peak $(g peak_rss_bytes_max) B/rank, held-out distance mean $(kv "$TMP/d.csv" dist_mean_pct) % of the diagonal"
    done
    if [ "$FERREUS" = 1 ] && guard ferreus_rbf 1 "$n"; then
        t0=$(now)
        if ! RAYON_NUM_THREADS=$FERREUS_THREADS OMP_NUM_THREADS=$FERREUS_THREADS OPENBLAS_NUM_THREADS=$FERREUS_THREADS \
            python3 "$ROOT/jobs/bench/ferreus.py" "$TMP/p.xyz" "$FERREUS_GRID,$FERREUS_GRID,$FERREUS_GRID" > "$TMP/f.csv" 2> "$TMP/flog"; then
            echo "ferreus_rbf ranks=1 N=$n failed:" >> "$OUT/failed.txt"
            tail -20 "$TMP/flog" | sed 's/^/    /' >> "$OUT/failed.txt"
            echo "  ferreus_rbf N=$n: FAILED (see failed.txt)"
            continue
        fi
        wall=$(since "$t0")
        f() { kv "$TMP/f.csv" "$1"; }
        echo "ferreus_rbf,$(f points),1,$FERREUS_THREADS,linear,,,,,,,,,,,,,,,,$(f evaluate_s),,,$(f fit_s),$wall,$(f grid_nodes),,$(f peak_rss_bytes),,$(f max_at_points),,,," >> "$OUT/raw.csv"
        echo "  ferreus_rbf N=$n: fit $(f fit_s) s, evaluate ${FERREUS_GRID} grid $(f evaluate_s) s"
    fi
done
