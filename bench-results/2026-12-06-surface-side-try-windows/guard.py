"""What a guard on the side vote's try by the data's winding number would have done, from the
probe's counts (winding-probe.csv: for each set, the lattice nodes the try empties and fills, by
the winding number of the oriented data there, and the unsupported crossings before and after
the try) and the quality of the fits with the try (the default,
bench-results/2026-12-06-surface-side-try/quality) and without it (the recorded runs before it).

  python3 bench-results/2026-12-06-surface-side-try-windows/guard.py   (from the repository root)

A guard that turns down a kept try gives that set the fit without the try. Per rule: the kept
tries it turns down, how many of those sets the fit without the try brings nearer the truth and
farther by the sum of both distances, the sets meeting every quality target and that sum over
all 299 sets."""
import csv, os, sys
sys.path.insert(0, "jobs/bench")
from surface_compare import met
from surface_report import PEERS
from surface_robust import load

HERE = os.path.dirname(os.path.abspath(__file__))
src = open(os.path.join(HERE, "..", "2026-12-06-surface-side-try", "tally.py")).read()
exec(src[src.index('B="bench-results"'):src.index("full={}")])  # base_dirs, peer_dirs
exp = "bench-results/2026-12-06-surface-side-try/quality"
probe = {}
for r in csv.DictReader(open(os.path.join(HERE, "winding-probe.csv"))):
    e = [int(r[k]) for k in ("emptied_w_below_0.1", "emptied_w_0.1_0.3", "emptied_w_0.3_0.5", "emptied_w_0.5_0.7", "emptied_w_0.7_up")]
    probe[(r["sampling"], r["set"])] = dict(E=int(r["emptied"]), eh=e, before=int(r["unsupported_before"]), after=int(r["unsupported_after"]))
rows = []
for s in sorted(os.listdir(exp)):
    E = load(f"{exp}/{s}"); Bb = load(base_dirs[s]); Pp = load(peer_dirs[s])
    for name, by in E.items():
        e, b = by["default"], Bb[name]["default"]
        pe = {m: r for m, r in Pp[name].items() if m in PEERS and r["status"] == "ok"}
        f = lambda r: float(r["t2m_rms_pct"]) + float(r["m2t_rms_pct"])
        rows.append((probe.get((s, name)), f(b), f(e), met(name, b, pe), met(name, e, pe)))


def evaluate(rule, label):
    tot = ok = trig = better = worse = 0
    for p, fb, fe, mb, me in rows:
        if p is not None and p["after"] < p["before"] and rule(p):
            trig += 1; tot += fb; ok += mb; better += fb < fe - 1e-9; worse += fb > fe + 1e-9
        else:
            tot += fe; ok += me
    print(f"{label:42} turned down {trig:3}  nearer {better:3} farther {worse:3}  met {ok}  sum {tot:.2f}")


print(f"{len(rows)} sets, {len(probe)} with a try")
evaluate(lambda p: False, "the try as it is (no guard)")
evaluate(lambda p: True, "every kept try turned down (= off)")
for t in (5, 10, 20, 30, 40):
    evaluate(lambda p, t=t: sum(p["eh"][2:]) >= t, f"at least {t} emptied nodes with w >= 0.3")
    evaluate(lambda p, t=t: sum(p["eh"][3:]) >= t, f"at least {t} emptied nodes with w >= 0.5")
for fr in (0.2, 0.3, 0.4, 0.5):
    evaluate(lambda p, fr=fr: p["E"] > 0 and sum(p["eh"][2:]) > fr * p["E"], f"over {fr} of the emptied with w >= 0.3")
    evaluate(lambda p, fr=fr: p["E"] > 0 and sum(p["eh"][3:]) > fr * p["E"], f"over {fr} of the emptied with w >= 0.5")
# the same turn-downs by the size of the try's gain alone: kept only where it removes more
for m in (1, 2, 3, 5, 10):
    evaluate(lambda p, m=m: p["before"] - p["after"] <= m, f"a gain of {m} crossings or fewer")
for fr in (0.005, 0.01, 0.02, 0.03, 0.05):
    evaluate(lambda p, fr=fr: p["before"] - p["after"] <= fr * p["before"], f"a gain of {fr} of the crossings or less")
