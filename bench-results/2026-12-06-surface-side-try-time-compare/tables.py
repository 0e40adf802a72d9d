"""Every sampling timed with the side vote's try (the default since 16868dc) against the same
sampling timed before it, and the README's tables of the default over all samplings.

  python3 bench-results/2026-12-06-surface-side-try-time-compare/tables.py   (from the repository root)

Runs with the try: bench-results/2026-12-06-surface-SAMPLING-side-try-time (seed 14:
-seed14-held-out-side-try-time, seed 13: -seed13-held-out-side-try-time), methods default and
carrier. Before it: 2026-12-05-surface-SAMPLING-smoother-time (13 and 14: -held-out-smoother).
Poisson's rows, for the tables' peers, from 2026-12-05-surface-SAMPLING-outside-time (13 and 14:
-held-out-fold), as in the README's table before the try. Prints, per set over 3x and per
sampling, the default's fit time over the carrier's with and before the try, the default's time
with the try over its time before (median per set), then the tables of
jobs/bench/surface_samplings.py on the runs with the try merged with Poisson's rows."""
import csv, os, statistics, subprocess, sys, tempfile

B = "bench-results"
SAMPLINGS = [f"seed{s}" for s in range(1, 15)] + ["strided"]


def folder(date, s, tag):
    held = s in ("seed13", "seed14")
    if tag == "side-try-time":
        return f"{B}/{date}-surface-{s}{'-held-out' if held else ''}-side-try-time"
    if tag == "smoother-time":
        return f"{B}/{date}-surface-{s}-held-out-smoother" if held else f"{B}/{date}-surface-{s}-smoother-time"
    return f"{B}/{date}-surface-{s}-held-out-fold" if held else f"{B}/{date}-surface-{s}-outside-time"


def rows(path):
    return list(csv.DictReader(open(os.path.join(path, "raw.csv"))))


def by_key(rs):
    return {(r["set"], r["method"]): r for r in rs}


ratios, before, speed, over = [], [], [], []
labels = []
with tempfile.TemporaryDirectory() as tmp:
    for s in SAMPLINGS:
        new = folder("2026-12-06", s, "side-try-time")
        if not os.path.exists(os.path.join(new, "raw.csv")):
            print(f"{s}: not timed with the try")
            continue
        A, O = by_key(rows(new)), by_key(rows(folder("2026-12-05", s, "smoother-time")))
        rs = []
        for (name, m), r in A.items():
            if m != "default" or (name, "carrier") not in A:
                continue
            d, c = float(r["fit_s"]), float(A[(name, "carrier")]["fit_s"])
            d0, c0 = float(O[(name, "default")]["fit_s"]), float(O[(name, "carrier")]["fit_s"])
            ratios.append(d / c); before.append(d0 / c0); speed.append((d / c) / (d0 / c0)); rs.append(d / c)
            if d / c > 3:
                over.append(f"  {s} {name}: {d:.3f} / {c:.3f} s = {d / c:.2f}x (before the try {d0 / c0:.2f}x)")
        print(f"{s}: {min(rs):.2f}-{max(rs):.2f}x, median {statistics.median(rs):.2f} ({len(rs)} sets)")
        # the merged folder for the tables: the try's default and carrier rows, Poisson's recorded rows
        merged = os.path.join(tmp, s)
        os.makedirs(merged)
        peers = [r for r in rows(folder("2026-12-05", s, "outside-time")) if r["method"] == "poisson"]
        allrows = rows(new) + peers
        with open(os.path.join(merged, "raw.csv"), "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(rows(new)[0].keys()))
            w.writeheader()
            for r in allrows:
                w.writerow({k: r.get(k, "") for k in w.fieldnames})
        label = {"strided": "the scanner's vertices, strided"}.get(s, f"area-uniform, seed {s[4:]}")
        if s in ("seed13", "seed14"):
            label += " (held out)"
        labels.append(f"{label}={merged}")
    print(f"sets {len(ratios)}: with the try {min(ratios):.2f}-{max(ratios):.2f}x the carrier's, median "
          f"{statistics.median(ratios):.2f}, {sum(x > 3 for x in ratios)} over 3x; before it "
          f"{min(before):.2f}-{max(before):.2f}, median {statistics.median(before):.2f}, "
          f"{sum(x > 3 for x in before)} over 3x; ratio with / before, median per set "
          f"{statistics.median(speed):.3f} ({min(speed):.2f}-{max(speed):.2f})")
    print("\n".join(over) if over else "no set over 3x")
    print()
    sys.stdout.flush()
    subprocess.run([sys.executable, "jobs/bench/surface_samplings.py"] + labels, check=True)
