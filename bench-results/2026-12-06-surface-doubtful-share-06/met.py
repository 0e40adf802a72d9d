"""Quality targets met by a quality-only sweep of the default (SWEEP/S/raw.csv, S in 1..14 and strided)
against the peers (screened Poisson and the plain carrier method, from the runs that timed them), set by set
against a base sweep where one is given: the sets whose figures differ (truth -> mesh / mesh -> truth / %
of vertices beyond 2 %), with the outcome where it differs; then the counts and the sum of both distances.

  python3 bench-results/2026-12-06-surface-doubtful-share-06/met.py \
      bench-results/2026-12-06-surface-doubtful-share-06/quality bench-results/2026-12-06-surface-kept-columns/quality
(from the repository root)"""
import sys, os
sys.path.insert(0, "jobs/bench")

from surface_compare import met
from surface_report import PEERS
from surface_robust import load
B="bench-results"; P=f"{B}/2026-12-02-surface-robust-shared-normals"
peer={"1":P+"/seed1","2":P+"/seed2","strided":P+"/strided","10":f"{B}/2026-12-03-surface-seed10-held-out"}
peer.update({str(s):f"{B}/2026-12-02-surface-seed{s}-shared-normals" for s in range(3,10)})
peer.update({str(s):f"{B}/2026-12-04-surface-seed{s}-held-out" for s in (11,12)})
peer.update({str(s):f"{B}/2026-12-05-surface-seed{s}-held-out" for s in (13,14)})
exp=sys.argv[1]; base=sys.argv[2] if len(sys.argv)>2 else None
f=lambda r:(float(r["t2m_rms_pct"]),float(r["m2t_rms_pct"]),float(r["far2_pct"]))
n=ok=okb=0; se=sb=0.0; near=far=0
for s in sorted(os.listdir(exp)):
    if not os.path.exists(f"{exp}/{s}/raw.csv"): continue
    E=load(f"{exp}/{s}"); Pp=load(peer[s]); Bb=load(f"{base}/{s}") if base else None
    for name,by in E.items():
        e=by["default"]; pe={m:r for m,r in Pp[name].items() if m in PEERS and r["status"]=="ok"}
        m=met(name,e,pe); n+=1; ok+=m; fe=f(e); se+=fe[0]+fe[1]
        best=[min(float(r[k]) for r in pe.values()) for k in ("t2m_rms_pct","m2t_rms_pct")]
        line=f"{s:8} {name:22} {fe[0]:.3f}/{fe[1]:.3f}/{fe[2]:.2f}  peers best {best[0]:.3f}/{best[1]:.3f}"
        if Bb:
            b=Bb[name]["default"]; fb=f(b); mb=met(name,b,pe); okb+=mb; sb+=fb[0]+fb[1]
            if fb!=fe:
                d=(fe[0]+fe[1])-(fb[0]+fb[1]); near+=d<0; far+=d>0
                print(f"{s:8} {name:22} {fb[0]:.3f}/{fb[1]:.3f}/{fb[2]:.2f} -> {fe[0]:.3f}/{fe[1]:.3f}/{fe[2]:.2f}" + ("" if m==mb else f"  {'ok' if mb else 'MISS'} -> {'ok' if m else 'MISS'}"))
        elif not m: print("MISS", line)
print(f"sets {n}: met {okb if base else ''} -> {ok}; sum {sb:.2f} -> {se:.2f}; nearer {near} farther {far}")
