"""Summary of jobs/bench-surface-order: the methods on the same points in another order.

  python3 surface_order.py OUT [--with OTHER]

OUT/SAMPLING/raw.csv holds rows on permuted points (jobs/bench/surface.py --permute) of the
default or of the peers or both; OTHER, another such folder of the same permutation, fills the
methods OUT lacks (the default from one run and Poisson from another: both permuted). Every
method not permuted is taken as recorded. OUT/SAMPLING/baseline.txt names the folder of the
recorded run on the same sampling in the order drawn, whose raw.csv has the default and both
peers (carrier, poisson). Rows of the method `neighbours` or `index` (`--off-deal neighbours`,
the default's dealing, or `--off-deal index`, the dealing by the input order) stand in the
default's place where a run has no default rows. Per sampling and in all: the sets on which the default meets the
quality targets of jobs/bench/surface_report.py (both distances at or below the better peer, the
far fraction on clean sets of at least 1000 points; the time target is left out, as the permuted
runs are timed once) in the order drawn and in the permuted order, the sets whose figures moved,
and each set whose outcome flipped, with the figures. Writes OUT/summary.md, or with --with
OUT/summary-with-NAME.md (NAME: OTHER's last component)."""
import os
import statistics
import sys
from collections import OrderedDict

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from surface_report import PEERS, num, targets  # noqa: E402
from surface_robust import load  # noqa: E402

# a figure is said to have moved when it changes by more than this fraction
MOVED = 0.02


def quality(name, by_method):
    """(met, failed checks) of the quality targets of `default` on one set."""
    r = next(iter(by_method.values()))
    checks = targets(name, r["variant"], int(r["points"]), by_method, "default", time_key="-")
    return all(ok for _, ok, _ in checks), [f"{what} {detail}" for what, ok, detail in checks if not ok]


def figures(row):
    if row is None or row["status"] != "ok":
        return "failed" if row else "missing"
    return f"{row['t2m_rms_pct']} / {row['m2t_rms_pct']} / {row['far2_pct']} % / {row['components']}"


def best_peer(by_method):
    ok = [r for m, r in by_method.items() if m in PEERS and r["status"] == "ok"]
    return " / ".join(f"{min(num(p, k) for p in ok):.3g}" for k in ("t2m_rms_pct", "m2t_rms_pct")) if ok else "-"


def main(out, also=None):
    samplings = [d for d in sorted(os.listdir(out), key=lambda s: (s == "strided", len(s), s))
                 if os.path.exists(os.path.join(out, d, "baseline.txt"))]
    if not samplings:
        sys.exit(f"surface_order: no OUT/SAMPLING/baseline.txt under {out}")
    flips, deltas, total, permuted = [], OrderedDict(), [0, 0, 0, 0, 0, 0], set()
    dealt = None
    table = []
    for s in samplings:
        base_dir = open(os.path.join(out, s, "baseline.txt")).read().strip()
        base = load(base_dir)
        perm = load(os.path.join(out, s))
        for by in perm.values():
            # a run of an --off-deal option is judged in the default's place
            for deal in ("neighbours", "index"):
                if deal in by and "default" not in by:
                    by["default"] = by.pop(deal)
                    dealt = deal
        if also:
            # rows of another run of the same permutation fill the methods this one lacks
            for name, by in load(os.path.join(also, s)).items():
                for m, r in by.items():
                    perm.setdefault(name, OrderedDict()).setdefault(m, r)
        n = met0 = met1 = lost = gained = moved = 0
        for name, by in perm.items():
            if name not in base:
                continue
            b = base[name]
            permuted |= set(by)
            drawn = OrderedDict((m, r) for m, r in b.items() if m in PEERS or m == "default")
            # each method permuted where this run has it, else as recorded
            now = OrderedDict((m, by.get(m, r)) for m, r in drawn.items())
            ok0, _ = quality(name, drawn)
            ok1, why1 = quality(name, now)
            n, met0, met1 = n + 1, met0 + ok0, met1 + ok1
            rel = []
            for m, r in by.items():
                for key in ("t2m_rms_pct", "m2t_rms_pct"):
                    x0, x1 = num(b.get(m), key) if b.get(m) else None, num(r, key)
                    if x0 and x1 is not None:
                        rel.append(abs(x1 / x0 - 1))
                        deltas.setdefault((m, key), []).append(x1 / x0 - 1)
            moved += any(r > MOVED for r in rel) or not rel
            if ok0 != ok1:
                lost, gained = lost + ok0, gained + ok1
                flips.append(f"| {s} | {name} | {figures(b.get('default'))} | {figures(now.get('default'))} | "
                             f"{best_peer(drawn)} | {best_peer(now)} | "
                             f"{'lost: ' + '; '.join(why1) if ok0 else 'gained'} |")
        total = [t + x for t, x in zip(total, (n, met0, met1, lost, gained, moved))]
        table.append(f"| {s} | {base_dir} | {n} | {met0} | {met1} | {lost} | {gained} | {moved} |")
    names = ", ".join(sorted(permuted))
    if dealt:
        names = names.replace("default", f"default with --off-deal {dealt}")
    lines = [f"# Methods on permuted points: {names}", "",
             f"Permuted: {names}{f' (with the rows of {also})' if also else ''}; every other method as recorded.",
             "Quality targets of the default only (both distances at or below the better peer's, far <= 2 % on",
             "clean sets of at least 1000 points); the order drawn from the recorded runs named per sampling.",
             f"A set has moved when a permuted method's figure changed by more than {MOVED:.0%}.", "",
             "| sampling | baseline | sets | met as drawn | met permuted | lost | gained | moved |",
             "|---|---|---|---|---|---|---|---|"] + table
    lines.append(f"| all | | {' | '.join(str(x) for x in total)} |")
    lines += ["", "Relative change of the permuted methods' figures over as drawn (median of the absolute "
              "value; range):", ""]
    for (m, key), vals in deltas.items():
        lines.append(f"- {m} {key}: {statistics.median(abs(v) for v in vals):.1%} "
                     f"({min(vals):+.1%} to {max(vals):+.1%}) over {len(vals)} sets")
    lines += ["", "Sets whose outcome flipped (the default's truth -> mesh rms / mesh -> truth rms / far / "
              "components; the better peer's two distances):", "",
              "| sampling | set | default as drawn | default now | better peer as drawn | better peer now | |",
              "|---|---|---|---|---|---|---|"] + flips
    name = f"summary-with-{os.path.basename(os.path.normpath(also))}.md" if also else "summary.md"
    open(os.path.join(out, name), "w").write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    if len(sys.argv) == 2:
        main(sys.argv[1])
    elif len(sys.argv) == 4 and sys.argv[2] == "--with":
        main(sys.argv[1], sys.argv[3])
    else:
        sys.exit(__doc__)
