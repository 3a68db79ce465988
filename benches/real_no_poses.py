#!/usr/bin/env python3
"""The real apartment LAZ planned with and without its pose sidecar: IoU of the story polygons
and the estimated scanner positions against the sidecar's.
Usage: benches/real_no_poses.py WITH_POSES.geojson WITHOUT.geojson POSES.json  (needs shapely)
Make the plans with:
  asbuilt plan apartment-merged.laz --poses apartment-merged.poses.json -o with.geojson -q
  asbuilt plan apartment-merged.laz -o without.geojson -q"""
import json, math, sys
from shapely.geometry import shape
from shapely.ops import unary_union

def stories(path):
    d = json.load(open(path))
    out = {}
    for f in d["features"]:
        p = f.get("properties") or {}
        if p.get("kind") == "story":
            out.setdefault(p.get("level"), []).append(shape(f["geometry"]))
    return d, {k: unary_union(v) for k, v in out.items()}

dw, sw = stories(sys.argv[1])
dn, sn = stories(sys.argv[2])
for lvl in sorted(set(sw) | set(sn), key=str):
    a, b = sw.get(lvl), sn.get(lvl)
    if a is None or b is None:
        print(f"level {lvl}: only in {'with' if b is None else 'without'}")
        continue
    iou = a.intersection(b).area / a.union(b).area
    print(f"level {lvl}: IoU {iou:.4f}, area with {a.area:.1f} m2, without {b.area:.1f} m2, valid {a.is_valid}/{b.is_valid}")
truth = {s["index"]: s["position"] for s in json.load(open(sys.argv[3]))["scans"]}
est = dn["floorplan"]["input"]["viewpoints"]["scans"]
print("| scan | sidecar x, y, z | estimated x, y, z | horizontal err cm | vertical err cm | residual cm | support |")
print("|---|---|---|---|---|---|---|")
hs = []
for s in est:
    t, p = truth[s["index"]], s.get("position")
    if p is None:
        print(f"| {s['index']} | {t[0]:.3f}, {t[1]:.3f}, {t[2]:.3f} | not located | | | | |")
        continue
    h = math.hypot(p[0] - t[0], p[1] - t[1]) * 100
    hs.append(h)
    print(f"| {s['index']} | {t[0]:.3f}, {t[1]:.3f}, {t[2]:.3f} | {p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f} | {h:.1f} | {(p[2]-t[2])*100:.1f} | {s['residual_m']*100:.1f} | {s['support']:.2f} |")
hs.sort()
print(f"located {len(hs)}/{len(est)}; horizontal error median {hs[len(hs)//2]:.1f} cm, max {hs[-1]:.1f} cm")
