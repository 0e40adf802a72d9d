"""Summary of a surface_compare.py output: the sets changed, the ratios exp / base of truth -> mesh,
mesh -> truth and far % over them (median, min, max), the means per variant group, and the
misses.  python3 summary.py COMPARE.txt"""
import re, sys, statistics
rows=[]
for l in open(sys.argv[1]):
    m=re.match(r'(\S+)\s+(\S+)\s+base ([\d.]+)/([\d.]+)/([\d.]+) (\w+)\s+exp ([\d.]+)/([\d.]+)/([\d.]+) (\w+)\s+peer ([\d.]+)/([\d.]+)',l)
    if not m: continue
    g=m.groups(); b=tuple(map(float,g[2:5])); e=tuple(map(float,g[6:9]))
    rows.append((g[0],g[1],b,e,g[5],g[9]))
ch=[r for r in rows if r[2]!=r[3]]
print(len(ch),'changed')
for k,name in ((0,'t2m'),(1,'m2t'),(2,'far')):
    r=[e[k]/b[k] for _,_,b,e,*_ in ch if b[k]>0]; print(name,'ratio median %.3f min %.3f max %.3f' % (statistics.median(r),min(r),max(r)))
for grp in ('open','clean','noise'):
    sel=[r for r in rows if grp in r[1]]
    for k,name in ((0,'t2m'),(1,'m2t')):
        print(grp,name,'mean base %.4f exp %.4f' % (statistics.mean(r[2][k] for r in sel), statistics.mean(r[3][k] for r in sel)))
for s,n,b,e,ob,oe in rows:
    if oe=='MISS' or ob=='MISS': print('  miss',s,n,b,'->',e)
