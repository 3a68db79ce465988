#!/usr/bin/env python3
# How far under the ceiling a floorless (phone) capture saw its walls, for comparing the
# simulator's ceiling_only capture with the real iPad rooms. Per 10 cm cell whose points lie
# mostly under the ceiling band and span at least 0.3 m, reach = ceiling - 2nd-percentile z;
# only the outermost cells of each 2-degree sector around the cloud's centre count (walls,
# not hanging clutter). Ceiling = top of the highest dense 5 cm level. Needs numpy.
#   python3 benches/phone-reach.py ../shared/data/real/ipad-room*.ply SIM/cloud.ply
# Also prints density: points per occupied 10 cm cell, overall and in the wall band 0.3-1.0 m under the ceiling.
# (SIM from `asbuilt simulate --building ceiling_only --ascii --keep plain --out SIM`)
import sys, numpy as np
def load(path):
    if path.endswith('.ply'):
        with open(path,'rb') as f:
            n=0; binary=False
            while True:
                l=f.readline().decode().strip()
                if l.startswith('element vertex'): n=int(l.split()[-1])
                if l.startswith('format') and 'binary' in l: binary=True
                if l=='end_header': break
            if binary: raise SystemExit('binary')
            a=np.loadtxt(f, max_rows=n, usecols=(0,1,2))
        return a
    return np.loadtxt(path, usecols=(0,1,2))
for path in sys.argv[1:]:
    p=load(path); z=p[:,2]
    h,e=np.histogram(z,bins=np.arange(z.min(),z.max()+0.05,0.05))
    top=np.where(h>h.max()*0.2)[0].max(); ceil=e[top+1]
    ij=np.floor(p[:,:2]/0.1).astype(np.int64); key=ij[:,0]*100000+ij[:,1]
    order=np.argsort(key); key=key[order]; zz=z[order]
    starts=np.r_[0,np.where(np.diff(key))[0]+1]; ends=np.r_[starts[1:],len(key)]
    reach=[]; cells=[]
    for s,t in zip(starts,ends):
        c=zz[s:t]
        if t-s<8: continue
        if np.mean(c<ceil-0.15)<0.6: continue
        lo=np.percentile(c,2); hi=np.percentile(c,98)
        if hi-lo<0.3 or hi<ceil-0.3: continue
        reach.append(ceil-lo); cells.append(key[s])
    r=np.array(reach); k=np.array(cells); xy=np.c_[k//100000, k%100000].astype(float)*0.1
    # Walls: the outermost cells in each 2-degree sector around the centre of all points.
    c=p[:,:2].mean(0); d=xy-c; ang=np.floor((np.degrees(np.arctan2(d[:,1],d[:,0]))+180)/2).astype(int); rad=np.hypot(d[:,0],d[:,1])
    far=np.zeros(180)
    np.maximum.at(far, ang, rad)
    outer=rad>=far[ang]-0.3
    r=r[outer]
    q=np.percentile(r,[10,25,50,75,90])
    occ=len(starts); band=np.sum((z<ceil-0.3)&(z>ceil-1.0))
    dens=f", {len(p)} points, {len(p)/occ:.1f} per occupied cell, {band/occ:.1f} per cell 0.3-1.0 m under the ceiling"
    print(f"{path.split('/')[-1]}: ceiling {ceil:.2f}, z {z.min():.2f}..{z.max():.2f}, wall cells {len(r)}, reach quantiles 10/25/50/75/90 % {np.round(q,2)}, share <0.6 m {np.mean(r<0.6):.2f}, <1.2 m {np.mean(r<1.2):.2f}, <2.0 m {np.mean(r<2.0):.2f}{dens}")
