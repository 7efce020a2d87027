import sys, math
# compare_tables.py BEFORE.tsv AFTER.tsv: per variant, geometric-mean CD ratio and inputs with the right topology (tables from evalall.sh)
exp={'box':2,'bun_zipper':2,'fandisk':2,'sphere':2,'spikes':0,'torus':0,'two_torus':-2}
def load(p):
    d={}
    for l in open(p):
        f=l.rstrip('\n').split('\t'); d[(f[0],f[1])]=f
    return d
a=load(sys.argv[1]); b=load(sys.argv[2])
ok=lambda r: r[4]=='1' and int(r[5])==exp[r[0]]
va=sorted({k[1] for k in b})
for v in va:
    ks=[k for k in b if k[1]==v and k in a]
    g=math.exp(sum(math.log(float(b[k][2])/float(a[k][2])) for k in ks)/len(ks))
    print(f"{v:15s} geo-mean CD ratio {g:.2f}  right topology {sum(ok(a[k]) for k in ks)}/{len(ks)} -> {sum(ok(b[k]) for k in ks)}/{len(ks)}")
print("all right topology", sum(ok(a[k]) for k in b if k in a), "->", sum(ok(b[k]) for k in b))
