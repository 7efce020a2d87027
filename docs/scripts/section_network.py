"""Cross-section network of a mesh, for benchmarking curve-network reconstruction.

usage: python section_network.py MESH OUT   (needs numpy and open3d)

Sections MESH with 5 planes per axis at (i + 0.5) / 5 of its bounding box,
chains the cut segments into polylines (closed where the mesh is), splits
segments longer than 0.5% of the diagonal, and writes OUT.obj (`l` lines),
OUT.xyz (the curve vertices) and OUT_oracle.xyz (vertices with the true
surface normals: the mean normal of the faces cut at each vertex), the
input of the oracle Poisson baseline (oracle_poisson.py).
"""
import sys, numpy as np, open3d as o3d
from collections import defaultdict
mesh = o3d.io.read_triangle_mesh(sys.argv[1]); out = sys.argv[2]
V = np.asarray(mesh.vertices); F = np.asarray(mesh.triangles)
FN = np.cross(V[F[:,1]]-V[F[:,0]], V[F[:,2]]-V[F[:,0]]); FN /= np.linalg.norm(FN,axis=1)[:,None]+1e-300
lo, hi = V.min(0), V.max(0); diag = np.linalg.norm(hi-lo)
verts, vnorm, lines = [], [], []
for axis in range(3):
    for k in range(5):
        c = lo[axis] + (k+0.5)/5*(hi[axis]-lo[axis])
        s = V[:,axis]-c; s[s==0] = 1e-12
        # per crossing edge: point keyed by sorted vertex pair
        pts, nrm, adj = {}, defaultdict(list), defaultdict(list)
        for fi,(a,b,cc) in enumerate(F):
            es = [(a,b),(b,cc),(cc,a)]
            cut = [tuple(sorted(e)) for e in es if s[e[0]]*s[e[1]]<0]
            if len(cut)!=2: continue
            for e in cut:
                if e not in pts:
                    t = s[e[0]]/(s[e[0]]-s[e[1]]); pts[e] = V[e[0]]+t*(V[e[1]]-V[e[0]])
                nrm[e].append(FN[fi])
            adj[cut[0]].append(cut[1]); adj[cut[1]].append(cut[0])
        seen=set()
        starts=[e for e in adj if len(adj[e])==1]+[e for e in adj if len(adj[e])==2]
        for e0 in starts:
            if e0 in seen: continue
            chain=[e0]; seen.add(e0); prev=None; cur=e0; closed=False
            while True:
                nxt=[x for x in adj[cur] if x!=prev]
                if not nxt: break
                n=nxt[0]
                if n==e0: closed=True; break
                if n in seen: break
                seen.add(n); chain.append(n); prev,cur=cur,n
            if len(chain)<3: continue
            P=[pts[e] for e in chain]; N=[np.mean(nrm[e],0) for e in chain]
            if closed: P.append(P[0]); N.append(N[0])
            # resample long segments (<= 0.5% diag)
            RP,RN=[P[0]],[N[0]]
            for i in range(1,len(P)):
                L=np.linalg.norm(P[i]-P[i-1]); m=int(np.ceil(L/(0.005*diag)))
                for j in range(1,m+1):
                    RP.append(P[i-1]+(P[i]-P[i-1])*j/m); RN.append(N[i-1]*(1-j/m)+N[i]*j/m)
            if closed: RP.pop(); RN.pop()
            base=len(verts); verts+=RP; vnorm+=RN
            idx=list(range(base+1,base+len(RP)+1)); 
            if closed: idx.append(base+1)
            lines.append(idx)
verts=np.array(verts); vnorm=np.array(vnorm); vnorm/=np.linalg.norm(vnorm,axis=1)[:,None]
with open(out+'.obj','w') as f:
    for p in verts: f.write('v %.7g %.7g %.7g\n'%tuple(p))
    for l in lines: f.write('l '+' '.join(map(str,l))+'\n')
np.savetxt(out+'_oracle.xyz', np.c_[verts,vnorm], fmt='%.7g')
np.savetxt(out+'.xyz', verts, fmt='%.7g')
print(out, 'points', len(verts), 'contours', len(lines), 'closed', sum(l[0]==l[-1] for l in lines))
