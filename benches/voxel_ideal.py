# The best plan that 8 cm voxel centres allow: every wall face of the truth moved to the centre of
# the voxel just on its open side (the outermost occupied voxel), scored against the truth.
#   target/release/examples/score dense_office_voxels 4000000 34 --out /tmp/vox
#   python3 benches/voxel_ideal.py /tmp/vox/truth.json
# Measured: IoU 0.980, boundary p95 0.040 m, 30 % of the boundary more than 2 cm off,
# completeness at 5 cm 1.000 (both levels).
import json,sys,math
from shapely.geometry import Polygon, LineString
from shapely.ops import unary_union
V=0.08
T=json.load(open(sys.argv[1]))
def q(c,s): return (math.floor((c+s*1e-6)/V)+0.5)*V
def quant_ring(r):
    r=r[:-1] if r[0]==r[-1] else r
    n=len(r); area=sum(r[i][0]*r[(i+1)%n][1]-r[(i+1)%n][0]*r[i][1] for i in range(n))/2
    ccw=1 if area>0 else -1
    # For edge i (r[i]->r[i+1]), the quantised coordinate of its fixed axis.
    eq=[]
    for i in range(n):
        a,b=r[i],r[(i+1)%n]
        d=(b[0]-a[0],b[1]-a[1])
        left=(-d[1],d[0])  # inside on the left for ccw
        out=(-left[0]*ccw,-left[1]*ccw)
        if abs(d[0])<1e-9: eq.append(('x',q(a[0],1 if out[0]>0 else -1)))
        else: eq.append(('y',q(a[1],1 if out[1]>0 else -1)))
    pts=[]
    for i in range(n):
        e1,e2=eq[i-1],eq[i]
        x=e1[1] if e1[0]=='x' else e2[1]; y=e1[1] if e1[0]=='y' else e2[1]
        pts.append((x,y))
    return pts
for lvl in (0,1):
    polys=[]; errs=[]
    truth=[]
    for f in T['features']:
        if f['geometry']['type']!='Polygon' or f['properties'].get('level',0)!=lvl: continue
        c=f['geometry']['coordinates']; tp=Polygon(c[0],c[1:]); truth.append(tp)
        polys.append(Polygon(quant_ring(c[0]),[quant_ring(h) for h in c[1:]]))
    t=unary_union(truth); p=unary_union(polys)
    pb=p.boundary; tb=t.boundary
    # plan-to-truth distances along the plan boundary (boundary error) and truth-to-plan (completeness)
    def samples(b,step=0.01):
        out=[]
        for g in (b.geoms if hasattr(b,'geoms') else [b]):
            L=g.length; n=int(L/step)
            out+= [g.interpolate((i+.5)*L/n) for i in range(n)]
        return out
    d=sorted(tb.distance(s) for s in samples(pb))
    c=[pb.distance(s) for s in samples(tb)]
    print('level',lvl,'ideal IoU %.4f'%(t.intersection(p).area/t.union(p).area),'p95 %.3f'%d[int(.95*len(d))],'mean %.4f'%(sum(d)/len(d)),
      'share >2cm %.3f'%(sum(1 for x in d if x>0.021)/len(d)), 'completeness5 %.3f'%(sum(1 for x in c if x<=0.05)/len(c)))
