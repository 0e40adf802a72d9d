"""The default method over several samplings of the surface benchmark, as the README gives it.

  python3 surface_samplings.py LABEL=FOLDER [LABEL=FOLDER ...]

Each FOLDER holds a raw.csv of jobs/bench/surface.py (one sampling: a run of jobs/bench-surface,
or a sub-folder of jobs/bench-surface-robust) with the methods default, carrier and poisson.
Prints markdown tables to standard output: per sampling, the sets on which the default meets every
target of jobs/bench/surface_report.py with the whole fit's time and without the preview picture
(`solid_s`, where recorded), the time ratios to the carrier method both ways, and the medians of
truth -> mesh / mesh -> truth / % of vertices beyond 2 % for the three methods; then the time
ratios by point count and the sets over 3x without the picture by variant."""
import os
import statistics
import sys
from collections import OrderedDict, defaultdict

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from surface_report import meets, num, time_ratios  # noqa: E402
from surface_robust import load  # noqa: E402

FIGURES = ("t2m_rms_pct", "m2t_rms_pct", "far2_pct")


def span(values):
    """min-max, median of a list of ratios, or - when empty."""
    if not values:
        return "-"
    return f"{min(values):.2f}-{max(values):.2f}, {statistics.median(values):.2f}"


def medians(sets, method):
    ok = [by[method] for by in sets.values() if method in by and by[method]["status"] == "ok"]
    if not ok:
        return "-"
    return " / ".join(f"{statistics.median(num(r, k) for r in ok):.3g}" for k in FIGURES)


def main(args):
    if not args or any("=" not in a for a in args):
        sys.exit(__doc__)
    runs = [a.split("=", 1) for a in args]
    totals = defaultdict(int)
    ratios = {"fit_s": [], "solid_s": []}
    by_size = defaultdict(lambda: {"fit_s": [], "solid_s": []})
    over_by_variant = OrderedDict()
    print("| sampling | sets | meeting every target, whole fit | time / carrier's: range, median "
          "| meeting every target without the picture | without the picture: range, median "
          "| default, medians | screened Poisson, medians | plain carrier method, medians |")
    print("|---|---|---|---|---|---|---|---|---|")
    for label, folder in runs:
        sets = load(folder)
        whole = sum(meets(name, by) for name, by in sets.items())
        solid = sum(meets(name, by, time_key="solid_s") for name, by in sets.items())
        rf, rs = time_ratios(sets, "default", "fit_s"), time_ratios(sets, "default", "solid_s")
        print(f"| {label} | {len(sets)} | {whole} | {span(rf)} | {solid if rs else '-'} | {span(rs)} | "
              f"{medians(sets, 'default')} | {medians(sets, 'poisson')} | {medians(sets, 'carrier')} |")
        totals["sets"] += len(sets)
        totals["whole"] += whole
        totals["solid"] += solid
        ratios["fit_s"] += rf
        ratios["solid_s"] += rs
        for by in sets.values():
            d, c = by.get("default"), by.get("carrier")
            if not (d and c and d["status"] == c["status"] == "ok"):
                continue
            for key in ratios:
                if num(d, key) and num(c, key):
                    by_size[int(d["n_requested"])][key].append(num(d, key) / num(c, key))
            if num(d, "solid_s") and num(c, "solid_s"):
                counts = over_by_variant.setdefault(d["variant"], [0, 0])
                counts[0] += num(d, "solid_s") / num(c, "solid_s") > 3
                counts[1] += 1
    print(f"| all | {totals['sets']} | {totals['whole']} | {span(ratios['fit_s'])} | "
          f"{totals['solid'] if ratios['solid_s'] else '-'} | {span(ratios['solid_s'])} | | | |")
    print()
    print("| points | sets | time / carrier's, whole fit: range, median | without the picture: range, median "
          "| over 3x, whole fit | over 3x without the picture |")
    print("|---|---|---|---|---|---|")
    for size in sorted(by_size):
        f, s = by_size[size]["fit_s"], by_size[size]["solid_s"]
        print(f"| {size} | {len(f)} | {span(f)} | {span(s)} | {sum(x > 3 for x in f)} | {sum(x > 3 for x in s)} |")
    if over_by_variant:
        print()
        print("Over 3x without the picture, by variant: " + ", ".join(
            f"{variant} {over} of {n}" for variant, (over, n) in over_by_variant.items()))


if __name__ == "__main__":
    main(sys.argv[1:])
