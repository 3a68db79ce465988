# What 8 cm voxel centres allow of the rooms' figures, against what the plan gives: every face of
# an axis-aligned truth room or wall moved to the centre of the voxel its points fall in (a
# point on a voxel boundary falls in the voxel above it, as the simulator's voxels key f32
# coordinates), then the bounds on that ideal.
#   target/release/examples/score dense_office_voxels 4000000 34 --out /tmp/vox
#   python3 benches/voxel_rooms_ideal.py /tmp/vox
# Per level: the story's IoU against the truth, ideal and plan (and plan against ideal); rooms
# within the area bound, ideal and plan; the worst area error of each; the largest interior
# wall thickness error, ideal and plan (the plan's centre lines measured as evaluate/rooms.rs
# does).
import json, math, sys
import numpy as np
from shapely.geometry import MultiPolygon, Polygon, shape
from shapely.ops import unary_union

V = 0.08
D = sys.argv[1]
T = json.load(open(D + '/truth.json'))
P = json.load(open(D + '/plan.geojson'))


def q(c):
    return (math.floor(float(np.float32(c)) / V) + 0.5) * V


def kind(doc, k, level):
    return [f for f in doc['features'] if f['properties'].get('kind') == k and f['properties']['level'] == level]


def quantised(g):
    polys = g.geoms if isinstance(g, MultiPolygon) else [g]
    return unary_union([Polygon([(q(x), q(y)) for x, y in p.exterior.coords],
                                [[(q(x), q(y)) for x, y in h.coords] for h in p.interiors]).buffer(0)
                        for p in polys])


def iou(a, b):
    return a.intersection(b).area / a.union(b).area


def within(a, t):
    e = abs(a - t)
    return e <= 0.01 * t or (t < 20 and e <= 0.2)


def truth_faces(faces, a, b):
    # The nearest truth faces parallel to a centre line on either side of its middle (0.5 m).
    u = np.subtract(b, a) / np.linalg.norm(np.subtract(b, a))
    n = np.array([-u[1], u[0]])
    m = (np.array(a) + np.array(b)) / 2
    left = right = None
    for p, r in faces:
        v = np.subtract(r, p)
        L = np.linalg.norm(v)
        v = v / L
        if abs(u[0] * v[1] - u[1] * v[0]) > 0.05 or not 0 <= (m - p) @ v <= L:
            continue
        s = (np.array(p) - m) @ n
        if 0 < s < 0.5 and (left is None or s < left[0]):
            left = (s, p)
        if -0.5 < s < 0 and (right is None or -s < right[0]):
            right = (-s, p)
    return left, right, n


for level in sorted({f['properties']['level'] for f in T['features'] if 'level' in f['properties']}):
    truth = [shape(f['geometry']) for f in kind(T, 'room', level)]
    if not truth:
        continue
    plan = [shape(f['geometry']) for f in kind(P, 'room', level)]
    ok_i = ok_p = 0
    worst_i = worst_p = 0.0
    for t in truth:
        ring = [(q(x), q(y)) for x, y in t.exterior.coords]
        ideal = Polygon(ring, [[(q(x), q(y)) for x, y in h.coords] for h in t.interiors]).area
        ok_i += within(ideal, t.area)
        worst_i = max(worst_i, abs(ideal - t.area) / t.area)
        best = max(plan, key=lambda p: p.intersection(t).area / p.union(t).area, default=None)
        if best is not None and best.intersection(t).area / best.union(t).area > 0.5:
            ok_p += within(best.area, t.area)
            worst_p = max(worst_p, abs(best.area - t.area) / t.area)
    faces = [f['geometry']['coordinates'] for f in kind(T, 'wall', level)]
    th_i = th_p = 0.0
    for f in kind(P, 'wall_centerline', level):
        if f['properties'].get('exterior'):
            continue
        a, b = f['geometry']['coordinates'][0], f['geometry']['coordinates'][-1]
        left, right, n = truth_faces(faces, a, b)
        if left is None or right is None:
            continue
        t = left[0] + right[0]
        th_p = max(th_p, abs(f['properties']['thickness_m'] - t))
        # Axis-aligned faces: the coordinate across the wall, quantised on each side.
        ax = 0 if abs(n[0]) > abs(n[1]) else 1
        th_i = max(th_i, abs(abs(q(left[1][ax]) - q(right[1][ax])) - t))
    story_t = unary_union([shape(f['geometry']) for f in kind(T, 'story', level)])
    story_p = unary_union([shape(f['geometry']) for f in kind(P, 'story', level)])
    story_i = quantised(story_t)
    print(f'level {level}: story IoU ideal {iou(story_i, story_t):.4f} plan {iou(story_p, story_t):.4f} '
          f'plan vs ideal {iou(story_p, story_i):.4f}')
    print(f'level {level}: rooms within bound ideal {ok_i}/{len(truth)} plan {ok_p}/{len(truth)}; '
          f'worst area error ideal {100 * worst_i:.2f} % plan {100 * worst_p:.2f} %; '
          f'wall thickness max error ideal {th_i:.3f} m plan {th_p:.3f} m')
