"""Summaries and plots of the benchmark jobs: reads OUT/raw.csv, writes OUT/summary.md and PNGs.
Usage: python3 report.py table1|table2|solve|eval|io|mesh|table1csrbf|scalecsrbf OUT"""
import csv
import os
import sys
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

mode, out = sys.argv[1], sys.argv[2]
rows = list(csv.DictReader(open(f"{out}/raw.csv")))
machine = open(f"{out}/machine.txt").read()
command = open(f"{out}/command.txt").read().strip()
lines = [f"# {mode}\n", f"Command: `{command}`\n", "```", machine.strip(), "```\n"]
cores = int([l for l in machine.splitlines() if l.startswith("cores:")][0].split()[1])

PAPER_T1 = {1: (180.2, 99.9), 2: (90.5, 99.4), 3: (62.5, 96.0), 6: (32.7, 92.0)}
PAPER_T2 = {184: (3.0, 6, 38), 377: (11, 42, 70), 628: (30, 192, 113), 942: (66, 633, 167)}
FLOPS = {"lu": 2 / 3, "dgetrf": 2 / 3, "pdgesv": 2 / 3, "solve": 2 / 3, "householder": 4 / 3,
         "dgeqrf": 4 / 3, "pdgeqrf": 4 / 3, "cholesky": 1 / 3, "pdpotrf": 1 / 3}


def best(group):
    """Best of the repetitions: the figure least disturbed by the rest of the machine."""
    return min(float(r["solve_s"]) for r in group)


if mode == "table1":
    data = defaultdict(list)
    for r in rows:
        data[(int(r["system_size"]), r["solver"], int(r["ranks"]))].append(r)
    sizes = sorted({k[0] for k in data})
    solvers = sorted({k[1] for k in data})
    fig, ax = plt.subplots(1, 2, figsize=(11, 4.2))
    for solver in solvers:
        for n in sizes:
            ranks = sorted(p for (s, sv, p) in data if s == n and sv == solver)
            t1 = best(data[(n, solver, 1)]) if (n, solver, 1) in data else None
            lines.append(f"\n## {solver}, system {n} x {n}\n")
            lines.append("| ranks | time (s) | processor use (%) | use of the cores (%) | speed-up | peak memory/rank (MB) | paper time (s) | paper use (%) |")
            lines.append("|---:|---:|---:|---:|---:|---:|---:|---:|")
            sp, eff = [], []
            for p in ranks:
                t = best(data[(n, solver, p)])
                mem = max(float(r["peak_rss_bytes"]) for r in data[(n, solver, p)]) / 1e6
                s = t1 / t if t1 else float("nan")
                e = 100 * s / p
                sp.append(s)
                eff.append(e)
                over = " (oversubscribed)" if p > cores else ""
                paper = PAPER_T1.get(p, ("", "")) if n == 400 and solver == "householder" else ("", "")
                ec = 100 * s / min(p, cores)
                lines.append(f"| {p}{over} | {t:.3f} | {e:.1f} | {ec:.1f} | {s:.2f} | {mem:.0f} | {paper[0]} | {paper[1]} |")
            ax[0].plot(ranks, sp, marker="o", label=f"{solver} {n}")
            ax[1].plot(ranks, eff, marker="o", label=f"{solver} {n}")
    pmax = max(k[2] for k in data)
    ax[0].plot([1, pmax], [1, pmax], "k:", label="ideal")
    ax[0].set(xlabel="ranks", ylabel="speed-up", title="Speed-up of the solution")
    ax[1].set(xlabel="ranks", ylabel="processor use (%)", title=f"Parallel efficiency ({cores} cores)")
    ax[1].axvline(cores + 0.5, color="grey", ls="--")
    for a in ax:
        a.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(f"{out}/speedup.png", dpi=110)
    fig, ax = plt.subplots(figsize=(6, 4.2))
    for solver in solvers:
        for p in sorted({k[2] for k in data}):
            ns = [n for n in sizes if (n, solver, p) in data]
            ax.loglog(ns, [best(data[(n, solver, p)]) for n in ns], marker="o", label=f"{solver}, {p} ranks")
    ax.set(xlabel="system size N+k", ylabel="time (s)", title="Solution time against size")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(f"{out}/time_vs_n.png", dpi=110)
    engines = sorted({r.get("gemm") or "not recorded" for r in rows})
    lines.append(f"\nLocal products (fit --gemm, as in effect): {', '.join(engines)}.")
    lines.append("\nPaper: Savchenko et al. (1995), Table 1: INMOS T800 transputers, 400 x 400 system, "
                 "Householder. Processor use here is T1 / (P TP) as there; use of the cores is T1 / (min(P, cores) TP), the figure that "
                 "matters when ranks share cores. Plots: speedup.png, time_vs_n.png.")

elif mode == "table2":
    lines.append("| points | solver | matrix formation (s) | solution of the SLAE (s) | evaluation of grid nodes (s) | nodes | paper (s): formation / solution / 10000 nodes |")
    lines.append("|---:|---|---:|---:|---:|---:|---|")
    per = defaultdict(list)
    for r in rows:
        p = int(r["points"])
        paper = " / ".join(str(v) for v in PAPER_T2[p]) if p in PAPER_T2 else ""
        solver = r["solver"] if r["solver"] == r["solver_used"] else f"{r['solver']} ({r['solver_used']})"
        lines.append(f"| {p} | {solver} | {float(r['matrix_formation_s']):.4f} | {float(r['solution_s']):.4f} | "
                     f"{float(r['evaluation_s']):.4f} | {r['grid_nodes']} | {paper} |")
        per[r["solver"]].append(r)
    fig, ax = plt.subplots(figsize=(6.5, 4.2))
    for solver, rs in per.items():
        n = [int(r["points"]) for r in rs]
        for col, style in [("matrix_formation_s", "--"), ("solution_s", "-"), ("evaluation_s", ":")]:
            ax.loglog(n, [float(r[col]) for r in rs], style, marker="o", label=f"{solver}: {col[:-2]}")
    ax.set(xlabel="points N", ylabel="time (s)", title=f"Table 2 columns, {rows[0]['ranks']} ranks")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(f"{out}/table2.png", dpi=110)
    lines.append("\nPaper: Savchenko et al. (1995), Table 2: Fobos, 6 transputers T800. Plot: table2.png.")

elif mode == "solve":
    lines.append("| implementation | operation | n | ranks | grid | threads/rank | time (s) | GFLOP/s | peak memory/rank (MB) | memory bound (MB) |")
    lines.append("|---|---|---:|---:|---|---:|---:|---:|---:|---:|")
    gf = {}
    for r in rows:
        n, t = int(r["n"]), float(r["seconds"])
        g = FLOPS[r["operation"]] * n**3 / t / 1e9
        p = int(r["ranks"])
        # raw.csv before the grid column: ScaLAPACK ran on P x 1
        grid = r.get("grid") or (f"{p}x1" if r["impl"] in ("volspline", "scalapack") else "")
        gridded = r["impl"] == "scalapack" or r["impl"].startswith("volspline-2d")
        gf[(r["impl"], r["operation"], n, p) + ((grid,) if gridded else ())] = (g, t)
        mem = f"{float(r['peak_rss_bytes']) / 1e6:.0f}" if r["peak_rss_bytes"] else ""
        bound = f"{1.15 * n * n * 8 / p / 1e6 + 200:.0f}" if r["impl"] == "volspline" else ""
        lines.append(f"| {r['impl']} | {r['operation']} | {n} | {p} | {grid} | {r['threads']} | {t:.3f} | {g:.1f} | {mem} | {bound} |")
    nmax = max(int(r["n"]) for r in rows)
    ranks = max(int(r["ranks"]) for r in rows)
    lines.append(f"\n## Targets at n = {nmax}, {ranks} ranks\n")

    def check(name, ours, ref, factor, higher=True):
        if ours is None or ref is None:
            lines.append(f"- {name}: not measured")
            return
        ok = ours >= factor * ref if higher else ours <= ref / factor
        lines.append(f"- {name}: {ours:.2f} vs {ref:.2f} -> {'met' if ok else 'MISSED'}")

    get = lambda *k: gf.get(k, (None, None))  # noqa: E731
    row = f"{ranks}x1"
    check("LU GFLOP/s >= 0.9 x dgetrf", get("volspline", "lu", nmax, ranks)[0], get("lapack", "dgetrf", nmax, 1)[0], 0.9)
    check("Householder GFLOP/s >= 0.9 x dgeqrf", get("volspline", "householder", nmax, ranks)[0], get("lapack", "dgeqrf", nmax, 1)[0], 0.9)
    check("Cholesky path time <= scipy.linalg.solve time / 2", get("volspline", "cholesky", nmax, ranks)[1], get("scipy", "solve", nmax, 1)[1], 2, higher=False)
    check(f"LU time <= PDGESV time ({row})", get("volspline", "lu", nmax, ranks)[1], get("scalapack", "pdgesv", nmax, ranks, row)[1], 1, higher=False)
    check(f"Householder time <= PDGEQRF time ({row})", get("volspline", "householder", nmax, ranks)[1], get("scalapack", "pdgeqrf", nmax, ranks, row)[1], 1, higher=False)
    check(f"projected Cholesky time <= PDPOTRF + PDPOTRS time ({row}) + 10 %", get("volspline", "cholesky", nmax, ranks)[1],
          1.1 * get("scalapack", "pdpotrf", nmax, ranks, row)[1] if get("scalapack", "pdpotrf", nmax, ranks, row)[1] else None, 1, higher=False)
    for grid in sorted({k[4] for k in gf if k[0].startswith("volspline-2d")}):
        pd = get("scalapack", "pdgesv", nmax, ranks, grid)[1]
        pc = get("scalapack", "pdpotrf", nmax, ranks, grid)[1]
        for impl, what in [("volspline-2d", "look-ahead off"), ("volspline-2d-lookahead", "look-ahead on")]:
            check(f"2D LU ({what}) time <= PDGESV time ({grid})", get(impl, "lu", nmax, ranks, grid)[1], pd, 1, higher=False)
            check(f"2D projected Cholesky ({what}) time <= PDPOTRF + PDPOTRS time ({grid}) + 10 %",
                  get(impl, "cholesky", nmax, ranks, grid)[1], 1.1 * pc if pc else None, 1, higher=False)
            check(f"2D Householder ({what}) time <= PDGEQRF time ({grid})", get(impl, "householder", nmax, ranks, grid)[1],
                  get("scalapack", "pdgeqrf", nmax, ranks, grid)[1], 1, higher=False)
    micro = f"{out}/micro_blas.csv"
    if os.path.exists(micro):
        with open(micro) as f:
            dgemm = max(float(r["gflops"]) for r in csv.DictReader(f) if r["kernel"] == "dgemm")
        limit = dgemm * ranks
        lines.append(f"- DGEMM rate (OpenBLAS, one core, best shape): {dgemm:.1f} GFLOP/s; {ranks} ranks: {limit:.1f}")
        together = f"{out}/micro_blas_concurrent.csv"
        if os.path.exists(together):
            with open(together) as f:
                rates = [r for r in csv.DictReader(f) if r["kernel"] == "dgemm"]
            # per copy its best shape; the slowest copy sets the pace of a collective algorithm
            best = {}
            for r in rates:
                best[r["copy"]] = max(best.get(r["copy"], 0.0), float(r["gflops"]))
            if best:
                slow = min(best.values())
                lines.append(f"- DGEMM rate of a core while all {len(best)} run one at once: "
                             f"{', '.join(f'{v:.1f}' for v in best.values())} GFLOP/s, the slowest "
                             f"{100 * slow / dgemm:.0f} % of one core alone (the ceiling of a GEMM-bound "
                             f"1 -> {len(best)} rank efficiency on this machine)")
        for key, (g, _) in sorted(gf.items()):
            if (key[0].startswith("volspline") or key[0] == "scalapack") and key[2] == nmax and key[3] == ranks:
                where = f" ({key[4]})" if len(key) > 4 else ""
                share = 100 * g / limit
                lines.append(f"- {key[0]} {key[1]}{where}: {g:.1f} GFLOP/s = {share:.0f} % of the DGEMM rate "
                             f"({'met' if share >= 75 else 'MISSED'} against 75 %)")
    local = f"{out}/gemm_rate.csv"
    if os.path.exists(local):
        with open(local) as f:
            local_rows = list(csv.DictReader(f))
        faer_rate = max(float(r["gflops"]) for r in local_rows if r["kernel"] == "faer_gemm")
        ours = [r for r in local_rows if r["kernel"].startswith("volspline_gemm_")]
        lines.append(f"- faer's product (gemm_rate.csv, one core, best shape): {faer_rate:.1f} GFLOP/s")
        # the solvers' kernel: volspline's product (the BLAS or faer, as `--gemm auto` chose), or
        # faer's in the runs of revisions before the choice
        kernel, rate = "faer's product", faer_rate
        if ours:
            kernel, rate = ours[0]["kernel"], max(float(r["gflops"]) for r in ours)
            lines.append(f"- volspline's product as the solvers call it ({kernel}, one core, best shape): "
                         f"{rate:.1f} GFLOP/s")
        solves = [r for r in local_rows if r["kernel"].startswith("volspline_trsm_")]
        if solves:
            blas_solves = {}
            if os.path.exists(micro):
                with open(micro) as f:
                    blas_solves = {(r["m"], r["k"]): r["gflops"] for r in csv.DictReader(f) if r["kernel"] == "trsm"}
            lines.append("- the panels' solve from the right (m rows against a k x k triangle, GFLOP/s): "
                         + ", ".join(f"{r['m']} x {r['k']}: {float(r['gflops']):.1f}"
                                     + (f" (OpenBLAS DTRSM {float(blas_solves[(r['m'], r['k'])]):.1f})"
                                        if (r["m"], r["k"]) in blas_solves else "")
                                     for r in solves))
        lines.append(f"- shares of the solvers' local kernel ({kernel}; {ranks} ranks: {rate * ranks:.1f} GFLOP/s), "
                     f"what the distribution and the panels lose apart from the kernel:")
        for key, (g, _) in sorted(gf.items()):
            if key[0].startswith("volspline") and key[2] == nmax:
                where = f" ({key[4]})" if len(key) > 4 else ""
                lines.append(f"  - {key[0]} {key[1]}{where}, {key[3]} rank(s): {100 * g / (rate * key[3]):.0f} %")
    for grid in sorted({k[4] for k in gf if k[0] == "scalapack" and k[4] != row}):
        for op in ["pdgesv", "pdgeqrf", "pdpotrf"]:
            a, b = get("scalapack", op, nmax, ranks, row)[1], get("scalapack", op, nmax, ranks, grid)[1]
            if a and b:
                lines.append(f"- ScaLAPACK {op}: {grid} grid {b:.2f} s against {row} {a:.2f} s ({a / b:.2f}x)")
    for solver in ["householder", "lu", "cholesky"]:
        for n in sorted({int(r["n"]) for r in rows}):
            t1, tp = get("volspline", solver, n, 1)[1], get("volspline", solver, n, ranks)[1]
            if t1 and tp:
                e = 100 * t1 / (ranks * tp)
                mark = ("met" if e >= 93 else "MISSED") if n >= 4000 else "latency bound, no target"
                lines.append(f"- parallel efficiency 1 -> {ranks} ranks, {solver}, n = {n}: {e:.1f} % ({mark})")
                tco = get("volspline-corun", solver, n, 1)[1]
                if tco:
                    lines.append(f"  - {ranks} one-rank solves at once: {tco:.3f} s against {t1:.3f} s alone, a ceiling "
                                 f"of {100 * t1 / tco:.1f} % on this machine; against it the distribution keeps "
                                 f"{100 * tco / (ranks * tp):.1f} %")
    for r in rows:
        if r["impl"] == "volspline" and r["peak_rss_bytes"]:
            n, p = int(r["n"]), int(r["ranks"])
            bound = 1.15 * n * n * 8 / p + 200e6
            if float(r["peak_rss_bytes"]) > bound:
                lines.append(f"- memory bound MISSED: {r['operation']} n={n} ranks={p}: {float(r['peak_rss_bytes']) / 1e6:.0f} MB > {bound / 1e6:.0f} MB")
    lines.append("- memory: every volspline row not listed above is within 1.15 (N+k)^2 8 / P + 200 MB")
    fig, ax = plt.subplots(figsize=(7, 4.5))
    series = defaultdict(list)
    for key, (g, _) in gf.items():
        impl, op, n, p = key[:4]
        label = f"{impl} {op} ({key[4]} grid)" if len(key) > 4 else f"{impl} {op} ({p} ranks)"
        series[label].append((n, g))
    for label, pts in sorted(series.items()):
        pts.sort()
        ax.plot([a for a, _ in pts], [b for _, b in pts], marker="o", label=label)
    ax.set(xlabel="n", ylabel="GFLOP/s (nominal flops)", title="Dense solvers on this machine")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(f"{out}/gflops.png", dpi=110)
    lines.append("\nTimes: the best of REPEAT runs of each (command.txt; single runs before REPEAT was added). "
                 "Nominal flops: LU 2/3 n^3, QR 4/3 n^3, Cholesky 1/3 n^3 (the projection's O(k n^2) not counted). "
                 "pdpotrf: PDPOTRF + PDPOTRS of one right-hand side on a symmetric positive definite matrix of the same "
                 "size (symmetrised random matrix + n I). Grid PRxPC: ScaLAPACK's process grid (blocks of NB); "
                 "volspline's rows are row-cyclic (P x 1, blocks of one row); volspline-2d: its three solvers "
                 "on the 2D block-cyclic layout of the grid, blocks of NB (-lookahead: the next panel factored and broadcast "
                 "during the trailing update). Plot: gflops.png.")

elif mode == "eval":
    lines.append("| implementation | points | grid nodes | threads | time (s) | kernel evaluations/s | max diff of U (relative) |")
    lines.append("|---|---:|---:|---:|---:|---:|---:|")
    rate = {}
    for r in rows:
        t = float(r["seconds"])
        rate[r["impl"]] = float(r["kernel_evals"]) / t
        lines.append(f"| {r['impl']} | {r['points']} | {r['grid_nodes']} | {r['threads_total']} | {t:.3f} | {rate[r['impl']]:.3e} | {r['max_rel_diff']} |")
    ratio = rate["volspline"] / rate["scipy"]
    lines.append(f"\n- throughput >= 4e9 kernel evaluations/s: {rate['volspline']:.3e} -> {'met' if rate['volspline'] >= 4e9 else 'MISSED'}")
    lines.append(f"- at least 30x scipy's RBFInterpolator: {ratio:.1f}x -> {'met' if ratio >= 30 else 'MISSED'}")
    ceiling = os.path.join(out, "sqrt_ceiling.csv")
    if os.path.exists(ceiling):
        c = {r["variant"]: r for r in csv.DictReader(open(ceiling))}
        if "sqrt" in c:
            per_core = rate["volspline"] / float(rows[0]["threads_total"])
            lines.append(
                f"- the hardware square root's ceiling (sqrt_ceiling.csv: the evaluator's inner loop alone, one core, "
                f"every root from the hardware): {float(c['sqrt']['kernel_evals_per_s']):.3e}/s against volspline's "
                f"{per_core:.3e}/s per thread (every third lane group's roots from multiply-adds, beside the "
                f"hardware's); rsqrt14 + 2 Newton steps (full precision) "
                f"{float(c['rsqrt14_newton2']['kernel_evals_per_s']):.3e}/s; rsqrt14 + 1 step "
                f"{float(c['rsqrt14_newton1']['kernel_evals_per_s']):.3e}/s with a relative error of "
                f"{float(c['rsqrt14_newton1']['max_rel_diff']):.1e} in the sums")
    fig, ax = plt.subplots(figsize=(5, 3.5))
    ax.bar(list(rate), list(rate.values()))
    ax.set(ylabel="kernel evaluations / s", yscale="log", title="Grid evaluation throughput")
    fig.tight_layout()
    fig.savefig(f"{out}/eval.png", dpi=110)

elif mode == "io":
    groups = defaultdict(list)
    for r in rows:
        groups[r["format"]].append(r)
    lines.append("| input | points | file (MB) | best time (s) | median time (s) | points/s | MB/s | repetitions |")
    lines.append("|---|---:|---:|---:|---:|---:|---:|---:|")
    for fmt, group in groups.items():
        times = sorted(float(r["seconds"]) for r in group)
        t, med = times[0], times[len(times) // 2]
        pts, mb = int(group[0]["points"]), int(group[0]["file_bytes"]) / 1e6
        lines.append(f"| {fmt} | {pts} | {mb:.1f} | {t:.4f} | {med:.4f} | {pts / t:.3e} | {mb / t:.0f} | {len(times)} |")
    lines.append("\nxyz: text list; ply_ascii / ply_binary / pcd_binary: float32 x, y, z; stl_binary: POINTS - 2 facets through "
                 "consecutive points, float32 corners merged into POINTS points; e57: one scan of float32 x, y, z under a "
                 "pose (a turn about z and a shift), written by the e57 crate; obj_bunny: tests/data/bunny10k.obj. "
                 "Each file is read whole through io::points::read_points; the files were just written, so they come "
                 "from the page cache: this measures parsing, not the disk.")

elif mode == "mesh":
    groups = defaultdict(list)
    for r in rows:
        groups[(int(r["n"]), int(r["threads"]))].append(r)
    lines.append("| grid | threads | polygonise best (s) | weld best (s) | cells/s (polygonise) | vertices | loop centres | triangles | closed | repetitions |")
    lines.append("|---|---:|---:|---:|---:|---:|---:|---:|---|---:|")
    for (n, threads), group in sorted(groups.items()):
        poly = min(float(r["polygonise_s"]) for r in group)
        wld = min(float(r["weld_s"]) for r in group)
        r = group[0]
        cells = (n - 1) ** 3
        lines.append(f"| {n}^3 | {threads} | {poly:.4f} | {wld:.4f} | {cells / poly:.3e} | {r['vertices']} | {r['loop_centres']} | {r['triangles']} | yes | {len(group)} |")
    lines.append("\nSphere of radius 0.8 on [-1, 1]^3, one slab (no MPI); bench_mesh stops with an error unless the "
                 "welded mesh is a closed oriented manifold, so every row listed is one.")


# The modes of the compactly supported (csrbf) studies: jobs/table1-csrbf and jobs/scale-csrbf.
# Their raw.csv leave a column empty where a run did not report it (e.g. dense dry runs).
import math  # noqa: E402
import os  # noqa: E402


def val(r, k):
    """The number in column k of row r, None where the run did not report it."""
    v = r.get(k)
    return float(v) if v not in (None, "") else None


def fmt(v, spec, none="—"):
    return none if v is None else format(v, spec)


def least(vals):
    vals = [v for v in vals if v is not None]
    return min(vals) if vals else None


def summed(r, *ks):
    vs = [val(r, k) for k in ks if val(r, k) is not None]
    return sum(vs) if vs else None


if mode == "table1csrbf":
    # Kojekine et al. (2001), Table 1: AMD Athlon 1 GHz (Pentium III 700 MHz in brackets)
    PAPER_CS = {
        "Head": dict(points="1487", leaf="10", tree="467 nodes at 6 levels", tree_s="0.05 (0.11)", support="0.2",
                     matrix_s="0.17 (0.98)", storage="426,811 of 2,211,169 (19.3 %)", solution_s="1.98 (1.722)",
                     rms="1.37e-08", max="4.49e-06"),
        "Seashell": dict(points="915", leaf="10", tree="291 nodes at 8 levels", tree_s="0.05 (0.07)", support="0.2",
                         matrix_s="0.1 (0.2)", storage="189,310 of 837,225 (22.6 %)", solution_s="0.61 (0.501)",
                         rms="5.81e-08", max="3.08e-05"),
    }
    groups = defaultdict(list)
    for r in rows:
        groups[(r["model"], r["paper_model"], r["kernel"], r["sparse_solver"])].append(r)
    models = list(dict.fromkeys((k[0], k[1]) for k in groups))
    plot = defaultdict(dict)
    for model, paper_model in models:
        keys = [k for k in groups if k[0] == model]
        paper = PAPER_CS[paper_model]
        cols = []
        for k in keys:
            rs = groups[k]
            r0 = rs[0]
            used = f" ({r0['kernel_used']}, {r0['solver_used'] or 'dense'})" if (r0["kernel_used"], r0["solver_used"]) != (k[2], k[3]) else ""
            stored, full = val(r0, "stored_entries"), val(r0, "full_entries")
            c = dict(
                head=f"{k[2]}, {k[3]}{used}", points=r0["points"], leaf=r0["leaf"] or "—",
                tree=f"{r0['tree_nodes']} nodes at {r0['tree_levels']} levels" if r0["tree_nodes"] else "—",
                tree_s=least(summed(r, "read_s", "tree_s") for r in rs) if r0["tree_s"] else None,
                read_s=least(val(r, "read_s") for r in rs),
                support=r0["support"] or "—", matrix_s=least(val(r, "assemble_s") for r in rs),
                factor_s=least(val(r, "factor_s") for r in rs), solve_s=least(val(r, "solve_s") for r in rs),
                solution_s=least(summed(r, "factor_s", "solve_s") for r in rs),
                storage=f"{stored:,.0f} of {full:,.0f} ({100 * stored / full:.1f} %)" if stored and full else "—",
                fill=fmt(val(r0, "fill"), ".2f"), nnz=f"{r0['nnz_row_mean'] or '—'} / {r0['nnz_row_max'] or '—'}",
                rms=fmt(val(r0, "rms_at_points"), ".2e"), max=fmt(val(r0, "max_at_points"), ".2e"),
                residual=fmt(val(r0, "residual"), ".2e"),
                mem=fmt(least(val(r, "peak_rss_bytes") / 1e6 for r in rs if val(r, "peak_rss_bytes")), ".1f"),
                reps=len(rs))
            cols.append(c)
            plot[model][c["head"]] = (c["tree_s"], c["matrix_s"], c["solution_s"],
                                      100 * stored / full if stored and full else None)
        lines.append(f"\n## {model} ({cols[0]['points']} points) beside the paper's {paper_model}\n")
        lines.append("| | paper: " + paper_model + " | " + " | ".join(c["head"] for c in cols) + " |")
        lines.append("|---|---|" + "---:|" * len(cols))
        table = [
            ("Number of points N", paper["points"], lambda c: c["points"]),
            ("Max. points in a leaf K", paper["leaf"], lambda c: c["leaf"]),
            ("Octree", paper["tree"], lambda c: c["tree"]),
            ("Tree creation, including file reading (s)", paper["tree_s"], lambda c: fmt(c["tree_s"], ".4f")),
            ("of which file reading (s)", "—", lambda c: fmt(c["read_s"], ".4f")),
            ("Selected radius r", paper["support"], lambda c: c["support"]),
            ("Matrix calculation (s)", paper["matrix_s"], lambda c: fmt(c["matrix_s"], ".4f")),
            ("Storage of A: stored entries of N^2", paper["storage"], lambda c: c["storage"]),
            ("Fill of the factor (`fill`)", "—", lambda c: c["fill"]),
            ("Nonzeros per row of A: mean / max", "—", lambda c: c["nnz"]),
            ("Factorisation (s)", "—", lambda c: fmt(c["factor_s"], ".4f")),
            ("Triangular solutions (s)", "—", lambda c: fmt(c["solve_s"], ".4f")),
            ("Solution by Cholesky decomposition (s)", paper["solution_s"], lambda c: fmt(c["solution_s"], ".4f")),
            ("RMS at the data", paper["rms"], lambda c: c["rms"]),
            ("MAX at the data", paper["max"], lambda c: c["max"]),
            ("Relative residual", "—", lambda c: c["residual"]),
            ("Peak memory (MB)", "128 MB machine", lambda c: c["mem"]),
        ]
        for name, p, get in table:
            lines.append(f"| {name} | {p} | " + " | ".join(str(get(c)) for c in cols) + " |")
        lines.append(f"\nTimes: best of {cols[0]['reps']} runs; stage maxima over ranks (one rank here).")
    lines.append(
        "\nPaper: Kojekine, Savchenko, Berzin, Hagiwara (2001), \"Software tools for compactly supported radial basis functions\", Table 1: \"Head\" and \"Seashell\" (not available; "
        "here evenly strided vertices of the repository's bunny and cow meshes in their place), AMD Athlon 1 GHz "
        "(Pentium III 700 MHz in brackets), envelope (profile) storage of the band of A and its Cholesky factor. "
        "Storage here: the entries the solver keeps (envelope or sparse factor) against N^2. Plot: table1csrbf.png.")
    fig, ax = plt.subplots(1, 2, figsize=(12, 4.4))
    labels, series = [], defaultdict(list)
    for model, paper_model in models:
        pm = PAPER_CS[paper_model]
        first = lambda s: float(s.split()[0])  # noqa: E731
        labels.append(f"paper {paper_model}")
        for i, key in enumerate(["tree_s", "matrix_s", "solution_s"]):
            series[i].append(first(pm[key]))
        series[3].append(float(pm["storage"].split("(")[1].split()[0]))
        for head, v in plot[model].items():
            labels.append(f"{model}: {head}")
            for i in range(4):
                series[i].append(v[i] if v[i] is not None else float("nan"))
    x = list(range(len(labels)))
    for i, name in enumerate(["tree", "matrix", "solution"]):
        ax[0].bar([a + (i - 1) * 0.27 for a in x], series[i], width=0.27, label=name)
    ax[0].set(yscale="log", ylabel="time (s)", title="Table 1 times (paper: Athlon 1 GHz)")
    ax[1].bar(x, series[3], color="grey")
    ax[1].set(ylabel="stored entries / N^2 (%)", title="Storage of A")
    for a in ax:
        a.set_xticks(x)
        a.set_xticklabels(labels, rotation=35, ha="right", fontsize=7)
    ax[0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(f"{out}/table1csrbf.png", dpi=110)

elif mode == "scalecsrbf":
    series = defaultdict(list)
    for r in rows:
        series[(r["impl"], int(r["ranks"]))].append(r)
    for rs in series.values():
        rs.sort(key=lambda r: int(r["points"]))

    def slope(pts):
        """Least-squares slope of log t against log N."""
        pts = [(math.log(n), math.log(t)) for n, t in pts if t and t > 0]
        if len({x for x, _ in pts}) < 2:
            return None
        mx = sum(x for x, _ in pts) / len(pts)
        my = sum(y for _, y in pts) / len(pts)
        return sum((x - mx) * (y - my) for x, y in pts) / sum((x - mx) ** 2 for x, _ in pts)

    lines.append("| implementation | ranks | threads/rank | N | kernel, support, leaf, solver | tree (s) | matrix (s) | factor (s) | solve (s) | fit (s) | "
                 "grid evaluation (s) | grid nodes | wall (s) | peak memory/rank (MB) | nonzeros/row mean / max | fill | "
                 "held-out distance mean / p95 / max (% of diagonal) | MAX at the data |")
    lines.append("|---|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|")
    for (impl, p), rs in sorted(series.items()):
        for r in rs:
            dist = " / ".join(fmt(val(r, k), ".3f") for k in ["dist_mean_pct", "dist_p95_pct", "dist_max_pct"])
            nnz = f"{fmt(val(r, 'nnz_row_mean'), '.1f')} / {fmt(val(r, 'nnz_row_max'), '.0f')}" if r["nnz_row_mean"] else "—"
            mem = val(r, "peak_rss_bytes")
            setting = ", ".join(r[k] or "—" for k in ["kernel", "support", "leaf", "sparse_solver"])
            lines.append(
                f"| {impl} | {p} | {r['threads']} | {int(r['points']):,} | {setting} | {fmt(val(r, 'tree_s'), '.3f')} | "
                f"{fmt(val(r, 'assemble_s'), '.3f')} | {fmt(val(r, 'factor_s'), '.3f')} | {fmt(val(r, 'solve_s'), '.3f')} | "
                f"{fmt(val(r, 'fit_s'), '.3f')} | {fmt(val(r, 'evaluate_s'), '.3f')} | {r['grid_nodes']} | {fmt(val(r, 'wall_s'), '.1f')} | "
                f"{fmt(mem / 1e6 if mem else None, '.0f')} | {nnz} | {fmt(val(r, 'fill'), '.2f')} | {dist} | "
                f"{fmt(val(r, 'max_at_points'), '.2e')} |")
    lines.append("\nfit = read + tree + matrix + factorisation + solution (stage maxima over ranks; ferreus_rbf: the "
                 "constructor, its whole fit); wall: the whole run (volspline: also the check, the grid evaluation, the "
                 "surface and the files). volspline evaluates its own grid inside the fit; ferreus_rbf a grid of its own "
                 "size (grid nodes column). MAX at the data: volspline's max |f| at the points as it reports it; "
                 "ferreus_rbf: max |s - f_c| at the points relative to max |f_c|.")
    lines.append("\n## Exponent of fit time in N (least squares of log fit time against log N)\n")
    lines.append("| implementation | ranks | sizes | exponent, all sizes | exponent, N >= 10^5 |")
    lines.append("|---|---:|---|---:|---:|")
    for (impl, p), rs in sorted(series.items()):
        pts = [(int(r["points"]), val(r, "fit_s")) for r in rs]
        big = [(n, t) for n, t in pts if n >= 100_000]
        lines.append(f"| {impl} | {p} | {', '.join(f'{n:,}' for n, _ in pts)} | {fmt(slope(pts), '.2f')} | {fmt(slope(big), '.2f')} |")
    vol = {p: {int(r["points"]): r for r in rs} for (impl, p), rs in series.items() if impl == "volspline"}
    if len(vol) > 1 and 1 in vol:
        lines.append("\n## Ranks: speed-up of fit and grid evaluation against 1 rank\n")
        lines.append("| N | ranks | fit speed-up | evaluation speed-up | peak memory/rank against 1 rank |")
        lines.append("|---:|---:|---:|---:|---:|")
        for p in sorted(vol):
            if p == 1:
                continue
            for n in sorted(set(vol[1]) & set(vol[p])):
                a, b = vol[1][n], vol[p][n]
                sp = lambda k: fmt(val(a, k) / val(b, k) if val(a, k) and val(b, k) else None, ".2f")  # noqa: E731
                lines.append(f"| {n:,} | {p} | {sp('fit_s')} | {sp('evaluate_s')} | {fmt(val(b, 'peak_rss_bytes') / val(a, 'peak_rss_bytes') if val(a, 'peak_rss_bytes') and val(b, 'peak_rss_bytes') else None, '.2f')} |")
    peer = {int(r["points"]): r for r in series.get(("ferreus_rbf", 1), [])}
    if peer and vol:
        lines.append("\n## Against ferreus_rbf\n")
        lines.append("| N | volspline ranks x threads | volspline fit (s) | ferreus_rbf fit (s) | fit ratio (ferreus / volspline) | "
                     "volspline grid nodes/s | ferreus_rbf grid nodes/s |")
        lines.append("|---:|---|---:|---:|---:|---:|---:|")
        for p in sorted(vol):
            for n in sorted(set(vol[p]) & set(peer)):
                a, b = vol[p][n], peer[n]
                ta, tb = val(a, "fit_s"), val(b, "fit_s")
                ra = val(a, "grid_nodes") / val(a, "evaluate_s") if val(a, "evaluate_s") else None
                rb = val(b, "grid_nodes") / val(b, "evaluate_s") if val(b, "evaluate_s") else None
                lines.append(f"| {n:,} | {p} x {a['threads']} | {fmt(ta, '.3f')} | {fmt(tb, '.3f')} | "
                             f"{fmt(tb / ta if ta and tb else None, '.2f')} | {fmt(ra, '.3e')} | {fmt(rb, '.3e')} |")
        lines.append(f"\nferreus_rbf: linear kernel |r| with a linear drift (the global spline of the dense method) on "
                     f"{next(iter(peer.values()))['threads']} threads, fitted to the carrier values of the same points.")
    for name in ["skipped", "failed"]:
        path = f"{out}/{name}.txt"
        if os.path.exists(path) and open(path).read().strip():
            lines.append(f"\n## {name.capitalize()} runs\n\n```\n{open(path).read().strip()}\n```")
    lines.append("\nPlots: scale_fit.png (fit time against N, log-log, least-squares lines), scale_stages.png "
                 "(volspline stages and peak memory against N).")
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    for (impl, p), rs in sorted(series.items()):
        pts = [(int(r["points"]), val(r, "fit_s")) for r in rs if val(r, "fit_s")]
        if not pts:
            continue
        e = slope(pts)
        line = ax.loglog([n for n, _ in pts], [t for _, t in pts], marker="o",
                         label=f"{impl}, {p} x {rs[0]['threads']}" + (f" (N^{e:.2f})" if e is not None else ""))
        if e is not None:
            mx = sum(math.log(n) for n, _ in pts) / len(pts)
            my = sum(math.log(t) for _, t in pts) / len(pts)
            ns = [pts[0][0], pts[-1][0]]
            ax.loglog(ns, [math.exp(my + e * (math.log(n) - mx)) for n in ns], ls=":", color=line[0].get_color())
    ax.set(xlabel="points N", ylabel="fit time (s)", title="Fit time against N (ranks x threads per rank)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(f"{out}/scale_fit.png", dpi=110)
    fig, ax = plt.subplots(1, 2, figsize=(12, 4.4))
    for (impl, p), rs in sorted(series.items()):
        ns = [int(r["points"]) for r in rs]
        if impl == "volspline" and p == min(q for i, q in series if i == "volspline"):
            for k in ["tree_s", "assemble_s", "factor_s", "solve_s", "evaluate_s", "mesh_s"]:
                got = [(n, val(r, k)) for n, r in zip(ns, rs) if val(r, k)]
                if got:
                    ax[0].loglog([n for n, _ in got], [t for _, t in got], marker="o", label=k[:-2])
        mem = [(n, val(r, "peak_rss_bytes") / 1e6) for n, r in zip(ns, rs) if val(r, "peak_rss_bytes")]
        if mem:
            ax[1].loglog([n for n, _ in mem], [m for _, m in mem], marker="o", label=f"{impl}, {p} x {rs[0]['threads']}")
    ax[0].set(xlabel="points N", ylabel="time (s)", title="volspline stages (fewest ranks)")
    ax[1].set(xlabel="points N", ylabel="peak memory per rank (MB)", title="Peak memory (ranks x threads per rank)")
    for a in ax:
        a.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(f"{out}/scale_stages.png", dpi=110)

open(f"{out}/summary.md", "w").write("\n".join(lines) + "\n")
print("\n".join(lines))
