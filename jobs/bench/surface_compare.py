"""Set-by-set comparison of an experiment's default rows with a recorded run of the default.

  python3 jobs/bench/surface_compare.py EXP [--base DIR] [--with SAMPLING=DIR ...]

EXP/SAMPLING/raw.csv holds rows of the method `default` (jobs/bench/surface.py, one sub-folder
per sampling: seedN or strided), made with a changed binary or an experiment hook. Each is
compared with the default's row of the same set in BASE/SAMPLING/raw.csv (default
bench-results/2026-12-04-surface-default-neighbours), whose BASE/SAMPLING/baseline.txt names the
recorded run holding the peers (carrier, poisson); `--with SAMPLING=DIR` takes a sampling's
default and peers from one run DIR instead (a sampling BASE lacks). Both rows are judged by the
quality targets of jobs/bench/surface_report.py (both distances at or below the better peer, the
far fraction on clean sets of at least 1000 points; times are left out). Prints one line per set
(truth -> mesh / mesh -> truth rms / far %, base and experiment, the better peer, GAINED or LOST
where the outcome flipped) and the counts. Run from the repository root."""
import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from surface_report import PEERS, targets  # noqa: E402
from surface_robust import load  # noqa: E402


def met(name, row, peers):
    """Whether `row` (the default's) meets the quality targets against `peers` on the set `name`."""
    by = dict(peers)
    by["default"] = row
    checks = targets(name, row["variant"], int(row["points"]), by, "default", time_key="-")
    return all(ok for _, ok, _ in checks)


def figures(row):
    return "/".join(f"{float(row[k]):.3f}" for k in ("t2m_rms_pct", "m2t_rms_pct")) + f"/{float(row['far2_pct']):.2f}"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("exp")
    ap.add_argument("--base", default="bench-results/2026-12-04-surface-default-neighbours")
    ap.add_argument("--with", dest="extra", action="append", default=[], metavar="SAMPLING=DIR")
    args = ap.parse_args()
    extra = dict(e.split("=", 1) for e in args.extra)
    counts = [0, 0, 0]
    for s in sorted(os.listdir(args.exp)):
        if not os.path.exists(os.path.join(args.exp, s, "raw.csv")):
            continue
        exp = load(os.path.join(args.exp, s))
        if s in extra:
            base = peers = load(extra[s])
        elif os.path.exists(os.path.join(args.base, s, "raw.csv")):
            base = load(os.path.join(args.base, s))
            peers = load(open(os.path.join(args.base, s, "baseline.txt")).read().strip())
        else:
            sys.exit(f"surface_compare: no {args.base}/{s}/raw.csv; name its run with --with {s}=DIR")
        for name, by in exp.items():
            e = by.get("default")
            b = base[name].get("default") or base[name].get("neighbours")
            pe = {m: r for m, r in peers[name].items() if m in PEERS and r["status"] == "ok"}
            if e is None or b is None or e["status"] != "ok" or not pe:
                print(f"{s:8} {name:22} missing or failed")
                continue
            ok_b, ok_e = met(name, b, pe), met(name, e, pe)
            counts[0] += 1
            counts[1] += ok_b
            counts[2] += ok_e
            best = "/".join(f"{min(float(p[k]) for p in pe.values()):.3f}" for k in ("t2m_rms_pct", "m2t_rms_pct"))
            flip = "" if ok_b == ok_e else (" GAINED" if ok_e else " LOST")
            print(f"{s:8} {name:22} base {figures(b)} {'ok ' if ok_b else 'MISS'}  "
                  f"exp {figures(e)} {'ok ' if ok_e else 'MISS'}  peer {best}{flip}")
    print(f"sets {counts[0]}: base met {counts[1]}, exp met {counts[2]}")


if __name__ == "__main__":
    main()
