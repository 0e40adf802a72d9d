"""Quality targets of a sweep of holed sets against the peers of another sweep, set by set.

  python3 jobs/bench/surface_holes.py SWEEP PEERS [BASE]

SWEEP/S/raw.csv gives the default's rows of each sampling S, PEERS/S/raw.csv screened Poisson's
and the plain carrier method's for the same sets, BASE/S/raw.csv (optional) the default's rows to
compare with. One line per set (truth -> mesh / mesh -> truth, % of the diagonal; met or MISS),
then the counts and the sums of both distances, in all and per variant."""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from surface_compare import met  # noqa: E402
from surface_report import PEERS  # noqa: E402
from surface_robust import load  # noqa: E402


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
            print(line)
    print(f"sets {n}: met {okb if base else ''} -> {ok}; sum {sb:.2f} -> {se:.2f}; nearer {near} farther {far}")
    for k, (vn, vo, vb) in sorted(per.items()):
        print(f"  {k}: {vn} sets, met {vb if base else ''} -> {vo}")


if __name__ == "__main__":
    if len(sys.argv) not in (3, 4):
        sys.exit(__doc__)
    compare(*sys.argv[1:])
