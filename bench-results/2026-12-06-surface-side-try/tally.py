"""Set-by-set figures of a quality-only sweep EXP (EXP/SAMPLING/raw.csv, method default) against
the recorded default (the smoother-time runs), the fits of `--orient-side both`
(2026-12-06-surface-orientation-experiments/both-compare.txt: the sets it changed) and the peers.

  python3 bench-results/2026-12-06-surface-side-try/tally.py EXP   (from the repository root)

One line per set that changed (or whose outcome differs): truth -> mesh / mesh -> truth rms in %
of the diagonal / % of vertices beyond 2 %, for the base, `both` and the experiment, with the
outcome where it differs; then per row the sets, those meeting every quality target and the sum of
both distances over all sets."""
import sys, os, re
sys.path.insert(0, "jobs/bench")
from surface_compare import met
from surface_report import PEERS
from surface_robust import load
B="bench-results"
base_dirs={f"seed{s}":f"{B}/2026-12-05-surface-seed{s}-smoother-time" for s in range(1,13)}
base_dirs.update(strided=f"{B}/2026-12-05-surface-strided-smoother-time", seed13=f"{B}/2026-12-05-surface-seed13-held-out-smoother", seed14=f"{B}/2026-12-05-surface-seed14-held-out-smoother")
P=f"{B}/2026-12-02-surface-robust-shared-normals"
peer_dirs={"seed1":P+"/seed1","seed2":P+"/seed2","strided":P+"/strided","seed10":f"{B}/2026-12-03-surface-seed10-held-out"}
peer_dirs.update({f"seed{s}":f"{B}/2026-12-02-surface-seed{s}-shared-normals" for s in range(3,10)})
peer_dirs.update({f"seed{s}":f"{B}/2026-12-04-surface-seed{s}-held-out" for s in (11,12)})
peer_dirs.update({f"seed{s}":f"{B}/2026-12-05-surface-seed{s}-held-out" for s in (13,14)})
full={}
for line in open(f"{B}/2026-12-06-surface-orientation-experiments/both-compare.txt"):
    m=re.match(r"(\S+)\s+(\S+) \[([^\]]*)\] -> \[([^\]]*)\]", line)
    if m: full[(m[1],m[2])]=[float(x) for x in m[4].split(",")]
exp=sys.argv[1]
tot={"base":[0,0,0],"exp":[0,0,0],"full":[0,0,0]}
for s in sorted(os.listdir(exp)):
    if not os.path.exists(f"{exp}/{s}/raw.csv"): continue
    E=load(f"{exp}/{s}"); Bb=load(base_dirs[s]); Pp=load(peer_dirs[s])
    for name, by in E.items():
        e=by["default"]; b=Bb[name]["default"]
        pe={m:r for m,r in Pp[name].items() if m in PEERS and r["status"]=="ok"}
        f=lambda r:(float(r["t2m_rms_pct"]),float(r["m2t_rms_pct"]),float(r["far2_pct"]))
        fb,fe=f(b),f(e)
        ff=full.get((s,name), list(fb))
        fr=dict(b); fr["t2m_rms_pct"],fr["m2t_rms_pct"],fr["far2_pct"]=map(str,ff)
        ok=[met(name,b,pe),met(name,e,pe),met(name,fr,pe)]
        for k,r,o in zip(["base","exp","full"],[fb,fe,ff],ok):
            tot[k][0]+=1; tot[k][1]+=o; tot[k][2]+=r[0]+r[1]
        flag=""
        if ok[0]!=ok[1] or ok[2]!=ok[1]: flag=f" base {'ok' if ok[0] else 'MISS'} full {'ok' if ok[2] else 'MISS'} exp {'ok' if ok[1] else 'MISS'}"
        if fe!=fb or flag:
            print(f"{s:8} {name:22} base {fb[0]:.3f}/{fb[1]:.3f}/{fb[2]:.2f} full {ff[0]:.3f}/{ff[1]:.3f}/{ff[2]:.2f} exp {fe[0]:.3f}/{fe[1]:.3f}/{fe[2]:.2f}{flag}")
for k,v in tot.items(): print(k, "sets",v[0],"met",v[1],"sum %.1f"%v[2])
