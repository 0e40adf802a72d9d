"""Summary of jobs/bench-surface-order: the default method on the same points in another order.

  python3 surface_order.py OUT

OUT/SAMPLING/raw.csv holds the default method's rows on permuted points (jobs/bench/surface.py
--permute), OUT/SAMPLING/baseline.txt the folder of the recorded run on the same sampling in the
order drawn, whose raw.csv has the default and both peers (carrier, poisson). Per sampling and in
all: the sets that meet the quality targets of jobs/bench/surface_report.py (both distances at or
below the better peer, the far fraction on clean sets of at least 1000 points; the time target is
left out, as the permuted runs are timed once) in the order drawn and in the permuted order, the
sets whose figures moved, and each set whose outcome flipped, with both figures. Writes
OUT/summary.md."""
import csv
import os
import statistics
import sys
from collections import OrderedDict

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from surface_report import PEERS, num, targets  # noqa: E402

# a figure is said to have moved when it changes by more than this fraction
MOVED = 0.02


def load(path):
    sets = OrderedDict()
    for r in csv.DictReader(open(path)):
        sets.setdefault(r["set"], OrderedDict())[r["method"]] = r
    return sets


def quality(name, by_method):
    """(met, failed checks) of the quality targets of `default` on one set."""
    r = next(iter(by_method.values()))
    checks = targets(name, r["variant"], int(r["points"]), by_method, "default", time_key="-")
    return all(ok for _, ok, _ in checks), [f"{what} {detail}" for what, ok, detail in checks if not ok]


def figures(row):
    if row is None or row["status"] != "ok":
        return "failed" if row else "missing"
    return f"{row['t2m_rms_pct']} / {row['m2t_rms_pct']} / {row['far2_pct']} % / {row['components']}"


def main(out):
    samplings = [d for d in sorted(os.listdir(out), key=lambda s: (s == "strided", len(s), s))
                 if os.path.exists(os.path.join(out, d, "raw.csv"))]
    if not samplings:
        sys.exit(f"surface_order: no OUT/SAMPLING/raw.csv under {out}")
    lines = ["# The default method on permuted points", "",
             "Quality targets only (both distances at or below the better peer's, far <= 2 % on clean sets of",
             "at least 1000 points); peers and the order drawn from the recorded runs named per sampling.",
             f"A figure has moved when it changed by more than {MOVED:.0%}.", "",
             "| sampling | baseline | sets | met as drawn | met permuted | lost | gained | moved |",
             "|---|---|---|---|---|---|---|---|"]
    flips, deltas, total = [], {"t2m_rms_pct": [], "m2t_rms_pct": []}, [0, 0, 0, 0, 0, 0]
    for s in samplings:
        base_dir = open(os.path.join(out, s, "baseline.txt")).read().strip()
        base = load(os.path.join(base_dir, "raw.csv"))
        perm = load(os.path.join(out, s, "raw.csv"))
        n = met0 = met1 = lost = gained = moved = 0
        for name, by in perm.items():
            if name not in base or "default" not in by:
                continue
            b = base[name]
            peers = OrderedDict((m, r) for m, r in b.items() if m in PEERS)
            ok0, why0 = quality(name, OrderedDict(peers, default=b.get("default")))
            ok1, why1 = quality(name, OrderedDict(peers, default=by["default"]))
            n, met0, met1 = n + 1, met0 + ok0, met1 + ok1
            d0, d1 = b.get("default"), by["default"]
            rel = []
            for key in deltas:
                x0, x1 = num(d0, key) if d0 else None, num(d1, key)
                if x0 and x1 is not None:
                    rel.append(abs(x1 / x0 - 1))
                    deltas[key].append(x1 / x0 - 1)
            moved += any(r > MOVED for r in rel) or not rel
            if ok0 != ok1:
                lost, gained = lost + ok0, gained + ok1
                best = {k: min(num(p, k) for p in peers.values() if p["status"] == "ok")
                        for k in ("t2m_rms_pct", "m2t_rms_pct")}
                flips.append(f"| {s} | {name} | {figures(d0)} | {figures(d1)} | "
                             f"{best['t2m_rms_pct']:.3g} / {best['m2t_rms_pct']:.3g} | "
                             f"{'lost: ' + '; '.join(why1) if ok0 else 'gained'} |")
        total = [t + x for t, x in zip(total, (n, met0, met1, lost, gained, moved))]
        lines.append(f"| {s} | {base_dir} | {n} | {met0} | {met1} | {lost} | {gained} | {moved} |")
    lines.append(f"| all | | {' | '.join(str(x) for x in total)} |")
    lines += ["", "Relative change of the default's figures, permuted over as drawn (median of the absolute "
              "value; range):", ""]
    for key, vals in deltas.items():
        if vals:
            lines.append(f"- {key}: {statistics.median(abs(v) for v in vals):.1%} "
                         f"({min(vals):+.1%} to {max(vals):+.1%}) over {len(vals)} sets")
    lines += ["", "Sets whose outcome flipped (truth -> mesh rms / mesh -> truth rms / far / components):", "",
              "| sampling | set | as drawn | permuted | better peer | |", "|---|---|---|---|---|---|"] + flips
    open(os.path.join(out, "summary.md"), "w").write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    main(sys.argv[1])
