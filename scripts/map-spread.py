"""How a map's returns spread about it, by range: each scan's returns placed by its
pose (a CARMEN log as published, or NDJSON beam frames with `pose`), their signed
distance to the nearest piece of the map (GeoJSON LineStrings, free side on the left),
and for the returns within 20 cm of the map:

- by range from their sensor: how many, the interquartile range of the signed distance
  and the share within 5 cm;
- the share within 5 cm of the map, and the share that one curve per half metre of
  wall could hold within 5 cm at best (each 0.5 m square's returns, a band of 10 cm slid
  across them to where it holds the most): what poses that disagree leave to any map
  with one curve a wall.

Usage: map-spread.py RECORDING MAP.geojson
"""
import gzip
import json
import math
import sys

import numpy as np
from scipy.spatial import cKDTree

REACH, WITHIN, CELL, BAND = 0.2, 0.05, 0.5, 0.1


def returns(path):
    """Every return within 20 m, placed by its scan's pose, and its range."""
    out = []
    for line in gzip.open(path, "rt") if path.endswith(".gz") else open(path):
        if line.startswith("{"):
            f = json.loads(line)
            if f.get("pose") is None or f.get("ranges") is None:
                continue
            r = np.array([v if v is not None else -1.0 for v in f["ranges"]], float)
            x, y, th = f["pose"]
            a = th + f["angle_min"] + f["angle_increment"] * np.arange(len(r))
            ok = (r > f.get("range_min", 0.0)) & (r < min(20.0, f.get("range_max", 20.0)))
        else:
            w = line.split()
            if not w or w[0] != "FLASER":
                continue
            n = int(w[1])
            r = np.array(list(map(float, w[2:2 + n])))
            x, y, th = map(float, w[2 + n:5 + n])
            # The old-style line's beams: 180 or 181 over 180 degrees, one a degree.
            inc = math.pi / 180 if n in (180, 181) else math.pi / (n - 1)
            a = th - math.pi / 2 + inc * np.arange(n)
            ok = (r > 0) & (r < 20.0)
        out.append(np.c_[x + r[ok] * np.cos(a[ok]), y + r[ok] * np.sin(a[ok]), r[ok]])
    pts = np.vstack(out)
    return pts[:, :2], pts[:, 2]


def segments(path):
    """The map's segments, as (start, end) arrays."""
    a, b = [], []
    for f in json.load(open(path))["features"]:
        g = f["geometry"]
        lines = {"LineString": [g["coordinates"]], "MultiLineString": g["coordinates"]}.get(g["type"], [])
        for c in lines:
            c = np.asarray(c, float)[:, :2]
            a.extend(c[:-1])
            b.extend(c[1:])
    return np.array(a), np.array(b)


def signed_distance(p, a, b):
    """Each point's signed distance to the nearest segment (positive on its left)."""
    ends = cKDTree(np.vstack([a, b, 0.5 * (a + b)]))
    m = len(a)
    # Candidate segments: those with an end or the middle among the 16 nearest.
    _, idx = ends.query(p, k=min(16, 3 * m))
    best = np.full(len(p), np.inf)
    sign = np.zeros(len(p))
    for k in range(idx.shape[1]):
        s = idx[:, k] % m
        sa, sb = a[s], b[s]
        ab = sb - sa
        t = np.clip(((p - sa) * ab).sum(1) / np.maximum((ab ** 2).sum(1), 1e-18), 0.0, 1.0)
        d = np.linalg.norm(p - (sa + t[:, None] * ab), axis=1)
        cr = ab[:, 0] * (p - sa)[:, 1] - ab[:, 1] * (p - sa)[:, 0]
        nearer = d < best
        best[nearer] = d[nearer]
        sign[nearer] = np.where(cr[nearer] >= 0, 1.0, -1.0)
    return best * sign


def main():
    p, r = returns(sys.argv[1])
    a, b = segments(sys.argv[2])
    sd = signed_distance(p, a, b)
    near = np.abs(sd) < REACH
    print(f"{len(p)} returns, {100 * near.mean():.1f}% within {100 * REACH:.0f} cm of the map")
    sd, p, r = sd[near], p[near], r[near]
    for lo, hi in [(0, 1), (1, 2), (2, 4), (4, 8), (8, 20)]:
        m = (r >= lo) & (r < hi)
        if m.sum() >= 100:
            q1, q3 = np.percentile(sd[m], [25, 75])
            print(f"  range {lo}-{hi} m: {m.sum()} returns, interquartile {100 * (q3 - q1):.1f} cm, "
                  f"{100 * (np.abs(sd[m]) < WITHIN).mean():.1f}% within {100 * WITHIN:.0f} cm")
    key = np.floor(p / CELL).astype(np.int64)
    key = key[:, 0] * 1_000_003 + key[:, 1]
    order = np.argsort(key, kind="stable")
    ks, ss = key[order], sd[order]
    cuts = np.r_[0, np.nonzero(np.diff(ks))[0] + 1, len(ks)]
    best = 0
    for i in range(len(cuts) - 1):
        s = np.sort(ss[cuts[i]:cuts[i + 1]])
        best += (np.searchsorted(s, s + BAND, side="right") - np.arange(len(s))).max()
    print(f"  within {100 * WITHIN:.0f} cm of the map: {100 * (np.abs(sd) < WITHIN).mean():.1f}%; "
          f"of one curve per {CELL} m of wall, at best: {100 * best / len(sd):.1f}%")


if __name__ == "__main__":
    main()
