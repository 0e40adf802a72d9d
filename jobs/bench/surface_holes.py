"""Quality targets of a sweep of holed sets against the peers of another sweep, set by set.

  python3 jobs/bench/surface_holes.py SWEEP PEERS [BASE]

SWEEP/S/raw.csv gives the default's rows of each sampling S, PEERS/S/raw.csv screened Poisson's
and the plain carrier method's for the same sets, BASE/S/raw.csv (optional) the default's rows to
compare with. One line per set (truth -> mesh / mesh -> truth, % of the diagonal; met or MISS),
then the counts and the sums of both distances, in all and per variant. Where SWEEP's and PEERS'
rows carry the split of both distances into the hole (the removed ball) and the rest (surface.py
writes it since the columns were added), each line ends with truth -> mesh in the hole and in the
rest for the default and the better peer there, and each variant's medians follow its count."""
import os
import statistics
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from surface_compare import met  # noqa: E402
from surface_report import HOLE, PEERS, num  # noqa: E402
from surface_robust import load  # noqa: E402


def split(row):
    """The row's distances in the hole and in the rest (HOLE's order; None for one the row lacks,
    as mesh -> truth in the hole of a mesh with no vertex there), or None where it has no split."""
    out = tuple(num(row, k) for k in HOLE)
    return None if out[0] is None else out


def compare(exp, peers, base=None):
    f = lambda r: (float(r["t2m_rms_pct"]), float(r["m2t_rms_pct"]))  # noqa: E731
    n = ok = okb = 0
    se = sb = 0.0
    near = far = 0
    per = {}
    for s in sorted(os.listdir(exp)):
        if not os.path.exists(f"{exp}/{s}/raw.csv"):
            continue
        E, P = load(f"{exp}/{s}"), load(f"{peers}/{s}")
        B = load(f"{base}/{s}") if base else None
        for name, by in sorted(E.items()):
            e = by["default"]
            pe = {m: r for m, r in P[name].items() if m in PEERS and r["status"] == "ok"}
            m = met(name, e, pe)
            v = per.setdefault(name.rsplit("-", 1)[1], [0, 0, 0])
            v[0] += 1
            v[1] += m
            n += 1
            ok += m
            fe = f(e)
            se += sum(fe)
            best = [min(float(r[k]) for r in pe.values()) for k in ("t2m_rms_pct", "m2t_rms_pct")]
            line = f"{s:8} {name:18} {fe[0]:.3f}/{fe[1]:.3f}  peers {best[0]:.3f}/{best[1]:.3f} {'ok' if m else 'MISS'}"
            if B:
                b = B[name]["default"]
                fb = f(b)
                mb = met(name, b, pe)
                okb += mb
                v[2] += mb
                sb += sum(fb)
                d = sum(fe) - sum(fb)
                near += d < 0
                far += d > 0
                line = (f"{s:8} {name:18} {fb[0]:.3f}/{fb[1]:.3f} -> {fe[0]:.3f}/{fe[1]:.3f}  peers {best[0]:.3f}/{best[1]:.3f}"
                        f" {'ok' if mb else 'MISS'} -> {'ok' if m else 'MISS'}")
            own = split(e)
            theirs = [x for x in (split(r) for r in pe.values()) if x]
            if own and theirs:
                best_split = tuple(min((x[k] for x in theirs if x[k] is not None), default=None) for k in range(4))
                v.append((own, best_split))
                line += (f"  hole {own[0]:.3f} (peer {best_split[0]:.3f}) rest {own[1]:.3f}"
                         f" (peer {best_split[1]:.3f})")
            print(line)
    print(f"sets {n}: met {okb if base else ''} -> {ok}; sum {sb:.2f} -> {se:.2f}; nearer {near} farther {far}")
    for k, (vn, vo, vb, *splits) in sorted(per.items()):
        print(f"  {k}: {vn} sets, met {vb if base else ''} -> {vo}")
        if splits:
            med = statistics.median
            for i, what in enumerate(HOLE):
                both = [(o[i], p[i]) for o, p in splits if o[i] is not None and p[i] is not None]
                if not both:
                    continue
                own, peer = zip(*both)
                below = sum(o <= p for o, p in both)
                print(f"    {what}: median {med(own):.3f} against the better peer's {med(peer):.3f};"
                      f" at or below it on {below} of {len(both)}"
                      + (f" (of {len(splits)}; on the others the default or every peer left no vertex there)"
                         if len(both) < len(splits) else ""))


if __name__ == "__main__":
    if len(sys.argv) not in (3, 4):
        sys.exit(__doc__)
    compare(*sys.argv[1:])
