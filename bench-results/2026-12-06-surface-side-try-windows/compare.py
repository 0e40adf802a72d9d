"""Set-by-set figures of two quality-only sweeps A and B of the default (A/SAMPLING/raw.csv, B/...):
truth -> mesh / mesh -> truth rms in % of the diagonal / % of vertices beyond 2 %, for each set whose
figures differ, with the outcome against the peers where it differs; then the counts and the sum of
both distances over all sets.

  python3 bench-results/2026-12-06-surface-side-try-windows/compare.py A B   (from the repository root)"""
import sys, os
sys.path.insert(0, "jobs/bench")
from surface_compare import met
from surface_report import PEERS
from surface_robust import load
src=open("bench-results/2026-12-06-surface-side-try/tally.py").read()
exec(src[src.index('B="bench-results"'):src.index("full={}")])
A,Bd=sys.argv[1],sys.argv[2]
tot=[0,0];ok=[0,0];n=0;near=far=0;lines=[]
for s in sorted(os.listdir(Bd)):
    if not os.path.exists(f"{Bd}/{s}/raw.csv"): continue
    Ea=load(f"{A}/{s}"); Eb=load(f"{Bd}/{s}"); Pp=load(peer_dirs[s])
    for name,by in Eb.items():
        a=Ea[name]["default"]; b=by["default"]
        pe={m:r for m,r in Pp[name].items() if m in PEERS and r["status"]=="ok"}
        f=lambda r:(float(r["t2m_rms_pct"]),float(r["m2t_rms_pct"]),float(r["far2_pct"]))
        fa,fb=f(a),f(b); ma,mb=met(name,a,pe),met(name,b,pe)
        n+=1; tot[0]+=fa[0]+fa[1]; tot[1]+=fb[0]+fb[1]; ok[0]+=ma; ok[1]+=mb
        if fa!=fb:
            d=(fb[0]+fb[1])-(fa[0]+fa[1]); near+=d<0; far+=d>0
            lines.append(f"{s:8} {name:22} {fa[0]:.3f}/{fa[1]:.3f}/{fa[2]:.2f} -> {fb[0]:.3f}/{fb[1]:.3f}/{fb[2]:.2f}"+("" if ma==mb else f"  {'ok' if ma else 'MISS'} -> {'ok' if mb else 'MISS'}"))
print("\n".join(lines))
print(f"sets {n}: changed {len(lines)}, nearer {near}, farther {far}; met {ok[0]} -> {ok[1]}; sum of both distances {tot[0]:.2f} -> {tot[1]:.2f}")
