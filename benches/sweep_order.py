# Rewrites a binary PLY of static scans (float x, y, z, uint scan_index; as `asbuilt bench` and
# `asbuilt simulate` write them) with each scan's points in the order a terrestrial scanner
# records them: scan by scan, then by azimuth column (0.09 degrees), then by elevation. The
# simulator casts its rays in random order, the worst case for the grid's passes; raw scanner
# exports come swept like this. Same points, other order.
#   python3 benches/sweep_order.py /work/bench-cache/office_3story-17400000/cloud.ply \
#       /work/bench-cache/office_3story-17400000/poses.json /tmp/office-swept.ply
import json
import sys

import numpy as np

src, poses, dst = sys.argv[1:4]
data = open(src, "rb").read()
end = data.index(b"end_header\n") + len(b"end_header\n")
header = data[:end].decode("ascii")
count = next(int(l.split()[2]) for l in header.splitlines() if l.startswith("element vertex"))
props = [l.split()[-1] for l in header.splitlines() if l.startswith("property")]
assert props == ["x", "y", "z", "scan_index"], props
rec = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("s", "<u4")])
a = np.frombuffer(data, dtype=rec, count=count, offset=end)
at = {p["index"]: p["position"] for p in json.load(open(poses))["scans"]}
pos = np.array([at[i] for i in range(max(at) + 1)])
s = a["s"]
d = np.stack([a["x"], a["y"], a["z"]], 1).astype(np.float64) - pos[s]
column = np.floor((np.arctan2(d[:, 1], d[:, 0]) + np.pi) / (2 * np.pi) * 4000).astype(np.int64)
elevation = np.arctan2(d[:, 2], np.hypot(d[:, 0], d[:, 1]))
order = np.lexsort((elevation, column, s))
with open(dst, "wb") as f:
    f.write(data[:end])
    f.write(a[order].tobytes())
