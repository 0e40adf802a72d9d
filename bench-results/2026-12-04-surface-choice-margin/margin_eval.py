import csv, os, sys, glob
R='/work/main/bench-results'; BASE=R+'/2026-12-04-surface-default-neighbours'
W='/tmp/exp/wide'
def rows(f): return list(csv.DictReader(open(f)))
shares={}
for d in glob.glob(W+'/log-*'):
    s=d.split('log-')[1]
    for f in glob.glob(d+'/*'):
        path,w,n,k=open(f).read().split()
        shares[(s,os.path.basename(path).rsplit('.',1)[0])]=(float(w),float(n))
data=[]
for s in ['1','2','3','4','5','6','7','8','9','10','strided']:
    sd='strided' if s=='strided' else 'seed'+s
    f=os.path.join(W,s,'raw.csv')
    if not os.path.exists(f): continue
    rec=open(os.path.join(BASE,sd,'baseline.txt')).read().strip()
    peers={}
    for r in rows(os.path.join('/work/main',rec,'raw.csv')):
        if r['method'] in ('carrier','poisson') and r['status']=='ok':
            p=peers.setdefault(r['set'],[9e9,9e9]); p[0]=min(p[0],float(r['t2m_rms_pct'])); p[1]=min(p[1],float(r['m2t_rms_pct']))
    base={r['set']:r for r in rows(os.path.join(BASE,sd,'raw.csv'))}
    for r in rows(f):
        n=r['set']; p=peers[n]
        def ok(x):
            q=float(x['t2m_rms_pct'])<=p[0] and float(x['m2t_rms_pct'])<=p[1]
            if x['variant']=='clean' and int(x['points'])>=1000: q=q and float(x['far2_pct'])<=2
            return q
        sh=shares.get((s,n))
        data.append((sd,n,sh,base[n],r,ok,p))
print('sets',len(data))
fig=lambda x: f"{float(x['t2m_rms_pct']):.3f}/{float(x['m2t_rms_pct']):.3f}/{float(x['far2_pct']):.2f}"
# consistency: where wide kept at margin 0, wide run should equal base
for sd,n,sh,b,w,ok,p in data:
    if sh and not sh[1]<sh[0] and fig(b)!=fig(w): print('inconsistent',sd,n,fig(b),fig(w))
    if sh is None and fig(b)!=fig(w): print('no-choice differs',sd,n,fig(b),fig(w))
for m in [0,0.01,0.02,0.05,0.1,0.15,0.2,0.3,0.5,1]:
    met=0; changed=[]
    for sd,n,sh,b,w,ok,p in data:
        if sh and sh[1]<sh[0]*(1-m): x=b
        elif sh and sh[1]<sh[0]: x=w; changed.append((sd,n))
        else: x=b
        met+=ok(x)
    print(f"margin {m}: met {met}, switched to wide {len(changed)}")
print()
for sd,n,sh,b,w,ok,p in data:
    if sh and sh[1]<sh[0]:
        rel=1-sh[1]/sh[0]
        print(f"{sd:8s} {n:20s} gain {rel:.3f} peer {p[0]:.3f}/{p[1]:.3f} narrow {fig(b)} {'ok' if ok(b) else 'NO'}  wide {fig(w)} {'ok' if ok(w) else 'NO'}")
