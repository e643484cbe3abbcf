#!/usr/bin/env python3
"""A textbook split-and-merge line extractor for 2D laser scans, as a baseline.

Reads isoline's NDJSON scan frames (beams: ranges, angle_min, angle_increment,
range_min, range_max) and writes one result record per frame in isoline's result
format, so that `isoline eval` scores both the same way:

    scripts/split_and_merge.py FRAMES.ndjson OUT.ndjson [--sigma 0.01]

1. The returns, in beam order, are clustered where consecutive ones are farther apart
   than the adaptive breakpoint distance (Borges & Aldon 2004, lambda = 10 degrees,
   plus 3 sigma sqrt 2): the same test isoline's runs use, so that the comparison is
   about the curves, not the clustering.
2. Each cluster is split recursively at the return farthest from the chord of its end
   returns while that distance exceeds max(3 sigma, 2 cm) (iterative end-point fit).
3. Neighbouring segments of a cluster are merged while the merged fit stays within the
   same tolerance.
4. Each segment of at least 3 returns becomes a line fitted by total least squares,
   drawn between the projections of its end returns.

Plain Python, no dependencies: the per-frame time it reports is that of a script.
"""

import json
import math
import sys
import time

LAMBDA = math.radians(10.0)
MIN_POINTS = 3


def returns(frame):
    a0, da = frame["angle_min"], frame["angle_increment"]
    lo, hi = frame.get("range_min", 0.0), frame["range_max"]
    out = []
    for i, r in enumerate(frame["ranges"]):
        if r is None or not (lo <= r < hi) or not math.isfinite(r):
            continue
        a = a0 + i * da
        out.append((i, a, r, (r * math.cos(a), r * math.sin(a))))
    if da < 0:
        out.reverse()
    return out


def clusters(rets, sigma):
    groups, cur = [], []
    for k, ret in enumerate(rets):
        if cur:
            i0, a0, r0, p0 = cur[-1]
            i1, a1, r1, p1 = ret
            dphi = abs(a1 - a0)
            reach = (
                min(r0, r1) * math.sin(dphi) / math.sin(LAMBDA - dphi) + 3 * math.sqrt(2) * sigma
                if dphi < LAMBDA
                else -1.0
            )
            if math.dist(p0, p1) > reach:
                groups.append(cur)
                cur = []
        cur.append(ret)
    if cur:
        groups.append(cur)
    return [[p for (_, _, _, p) in g] for g in groups]


def chord_dist(p, a, b):
    dx, dy = b[0] - a[0], b[1] - a[1]
    n = math.hypot(dx, dy)
    if n == 0:
        return math.dist(p, a)
    return abs(dx * (a[1] - p[1]) - dy * (a[0] - p[0])) / n


def split(pts, tol):
    if len(pts) < 3:
        return [pts]
    a, b = pts[0], pts[-1]
    k, d = max(((k, chord_dist(p, a, b)) for k, p in enumerate(pts)), key=lambda x: x[1])
    if d > tol and 0 < k < len(pts) - 1:
        return split(pts[: k + 1], tol) + split(pts[k:], tol)
    return [pts]


def fit(pts):
    """Total least squares line: centroid and unit direction; and the worst residual."""
    n = len(pts)
    cx = sum(p[0] for p in pts) / n
    cy = sum(p[1] for p in pts) / n
    sxx = sum((p[0] - cx) ** 2 for p in pts)
    syy = sum((p[1] - cy) ** 2 for p in pts)
    sxy = sum((p[0] - cx) * (p[1] - cy) for p in pts)
    theta = 0.5 * math.atan2(2 * sxy, sxx - syy)
    d = (math.cos(theta), math.sin(theta))
    worst = max(abs(-d[1] * (p[0] - cx) + d[0] * (p[1] - cy)) for p in pts)
    return (cx, cy), d, worst


def merge(segs, tol):
    out = [segs[0]]
    for s in segs[1:]:
        both = out[-1] + s[1:]
        if len(both) >= 3 and fit(both)[2] <= tol:
            out[-1] = both
        else:
            out.append(s)
    return out


def line(pts):
    c, d, _ = fit(pts)
    proj = lambda p: (p[0] - c[0]) * d[0] + (p[1] - c[1]) * d[1]
    s0, s1 = proj(pts[0]), proj(pts[-1])
    return [[c[0] + s0 * d[0], c[1] + s0 * d[1]], [c[0] + s1 * d[0], c[1] + s1 * d[1]]]


def extract(frame, sigma):
    tol = max(3 * sigma, 0.02)
    lines = []
    for cl in clusters(returns(frame), sigma):
        if len(cl) < MIN_POINTS:
            continue
        for seg in merge(split(cl, tol), tol):
            if len(seg) >= MIN_POINTS:
                lines.append({"closed": False, "points": line(seg)})
    return lines


def main():
    args = sys.argv[1:]
    sigma = 0.01
    if "--sigma" in args:
        k = args.index("--sigma")
        sigma = float(args[k + 1])
        del args[k : k + 2]
    src, dst = args
    times = []
    with open(src) as f, open(dst, "w") as out:
        for lineno, text in enumerate(f, 1):
            if not text.strip():
                continue
            frame = json.loads(text)
            t = time.perf_counter()
            pls = extract(frame, sigma)
            times.append((time.perf_counter() - t) * 1e3)
            rec = {"frame": frame["frame"], "polylines": pls}
            if "stream" in frame:
                rec["stream"] = frame["stream"]
            out.write(json.dumps(rec) + "\n")
    times.sort()
    print(f"split-and-merge: {len(times)} frames, median {times[len(times) // 2]:.1f} ms a frame",
          file=sys.stderr)


if __name__ == "__main__":
    main()
