"""Combined summary of jobs/bench-surface-robust: reads OUT/SAMPLING/raw.csv for each sampling
(jobs/bench/surface.py) and writes OUT/summary.md.

  python3 surface_robust.py OUT

Per method other than the peers (carrier, poisson): the sets that meet every target of
jobs/bench/surface_report.py on each sampling and in all, and the medians of both distances and of
the far fraction per sampling; then, per set, which samplings the method meets every target on. A
change tuned on one sample of the meshes shows here as a gain on that sampling and a loss on the
others."""
import csv
import os
import statistics
import sys
from collections import OrderedDict

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from surface_report import PEERS, meets, num, recorded, time_ratios  # noqa: E402


def load(folder):
    sets = OrderedDict()
    for r in csv.DictReader(open(os.path.join(folder, "raw.csv"))):
        sets.setdefault(r["set"], OrderedDict())[r["method"]] = r
    return sets


def main(out):
    samplings = [d for d in sorted(os.listdir(out)) if os.path.exists(os.path.join(out, d, "raw.csv"))]
    if not samplings:
        sys.exit(f"surface_robust: no OUT/SAMPLING/raw.csv under {out}")
    data = {s: load(os.path.join(out, s)) for s in samplings}
    methods = list(OrderedDict.fromkeys(m for s in samplings for by in data[s].values() for m in by
                                        if m not in PEERS))
    met = {}  # (method, sampling) -> {set: bool}, for the samplings the method ran on
    for m in methods:
        for s in samplings:
            if not any(m in by for by in data[s].values()):
                continue
            met[m, s] = OrderedDict((name, meets(name, by, m)) for name, by in data[s].items())
    lines = ["# bench-surface-robust: the surface benchmark on several samplings of the same meshes\n"]
    lines += recorded(out, ("command.txt", "machine.txt"))
    lines += ["Sets meeting every target (both distances at or below the better peer, at most 2 % far vertices "
              "on clean sets of at least 1000 points, fit time at most 3x the carrier method's; "
              "jobs/bench/surface_report.py), per sampling (each sub-folder has its own summary.md), "
              "and medians over the sets: truth->mesh rms / mesh->truth rms / % of vertices beyond 2 %, "
              "in % of the diagonal.\n",
              "| method | " + " | ".join(samplings) + " | all | " + " | ".join(f"medians {s}" for s in samplings) + " |",
              "|---|" + "---|" * (2 * len(samplings) + 1)]
    for m in methods:
        ran = [s for s in samplings if (m, s) in met]
        counts = [f"{sum(met[m, s].values())}/{len(met[m, s])}" if s in ran else "-" for s in samplings]
        total = f"{sum(sum(met[m, s].values()) for s in ran)}/{sum(len(met[m, s]) for s in ran)}"
        meds = []
        for s in samplings:
            ok = [by[m] for by in data[s].values() if m in by and by[m]["status"] == "ok"]
            if not ok:
                meds.append("-")
                continue
            med = lambda k: statistics.median(num(r, k) for r in ok)  # noqa: E731
            meds.append(f"{med('t2m_rms_pct'):.3g} / {med('m2t_rms_pct'):.3g} / {med('far2_pct'):.3g}")
        lines.append(f"| {m} | " + " | ".join(counts) + f" | {total} | " + " | ".join(meds) + " |")
    # the fit times without the preview picture (solid_s), where the runs recorded them
    solid_lines = []
    for m in methods:
        for s in samplings:
            ratios = time_ratios(data[s], m, "solid_s")
            if not ratios:
                continue
            met_solid = sum(meets(n, by, m, "solid_s") for n, by in data[s].items())
            solid_lines.append(f"| {m} | {s} | {met_solid}/{len(data[s])} | {min(ratios):.2f}-{max(ratios):.2f}x "
                               f"(median {statistics.median(ratios):.2f}x) | {sum(r <= 3.0 for r in ratios)}/{len(ratios)} |")
    if solid_lines:
        lines += ["", "The same with the fit times less the preview picture (solid_s = fit_s - render_s, both "
                  "methods; the fastest of the runs by itself):\n",
                  "| method | sampling | sets meeting every target | time over the carrier's | within 3x |",
                  "|---|---|---|---|---|"] + solid_lines
    names = list(OrderedDict.fromkeys(n for s in samplings for n in data[s]))
    for m in methods:
        lines += ["", f"Sets on which {m} meets every target (-: the set or the method is not in that sampling):\n",
                  "| set | " + " | ".join(samplings) + " |", "|---|" + "---|" * len(samplings)]
        for n in names:
            cells = ["-" if n not in met.get((m, s), {}) else ("yes" if met[m, s][n] else "no") for s in samplings]
            lines.append(f"| {n} | " + " | ".join(cells) + " |")
    with open(os.path.join(out, "summary.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
    print(f"surface_robust: {out}/summary.md")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    main(sys.argv[1])
