#!/usr/bin/env python3
"""How far an estimated trajectory's heading is off, for a recording without reference
poses made in a building whose walls meet at right angles: each scan's walls, placed
by the trajectory's heading, should run along the first scan's walls (modulo 90
degrees). For every scan from FROM on, `step` scans apart, the direction of its
straight stretches of returns (seven consecutive returns within 0.5 m whose spread
across is under a fifth of that along) is averaged modulo 90 degrees (the mean of
exp(4i angle)); a scan whose directions agree (that mean's length over 0.5) gives its
walls' heading. Prints the median of those headings, degrees, less the first scan's.

Usage: manhattan-heading.py FRAMES.ndjson[.gz] TRAJECTORY.tum FROM [STEP] [SKIP]
(SKIP: frames of FRAMES before the trajectory's first, when it was made from a later
start.)
"""
import cmath
import math
import statistics
import sys

import ndjson
import tum


def walls(frame, heading):
    """The mean of exp(4i angle) over the scan's straight stretches, in the world."""
    pts = []
    for i, r in enumerate(frame["ranges"]):
        if r is None or not 0.05 < r < frame.get("range_max", 1e9):
            continue
        a = frame["angle_min"] + i * frame["angle_increment"]
        pts.append((r * math.cos(a), r * math.sin(a)))
    total, n = 0j, 0
    for i in range(3, len(pts) - 3):
        q = pts[i - 3 : i + 4]
        if math.dist(q[0], q[-1]) > 0.5:
            continue
        mx = sum(p[0] for p in q) / 7
        my = sum(p[1] for p in q) / 7
        sxx = sum((p[0] - mx) ** 2 for p in q)
        syy = sum((p[1] - my) ** 2 for p in q)
        sxy = sum((p[0] - mx) * (p[1] - my) for p in q)
        # The covariance's eigenvalues: the stretch is straight when the smaller is
        # under a twenty-fifth of the larger (spreads a fifth apart).
        half, det = (sxx + syy) / 2, sxx * syy - sxy * sxy
        root = math.sqrt(max(half * half - det, 0.0))
        big, small = half + root, half - root
        if big <= 0 or small > big / 25:
            continue
        angle = 0.5 * math.atan2(2 * sxy, sxx - syy) + heading
        total += cmath.exp(4j * angle)
        n += 1
    return total / n if n >= 20 else None


def main():
    path, traj = sys.argv[1], tum.read(sys.argv[2])
    start = int(sys.argv[3])
    step = int(sys.argv[4]) if len(sys.argv) > 4 else 10
    skip = int(sys.argv[5]) if len(sys.argv) > 5 else 0
    all_frames = [f for f in ndjson.frames(path) if "ranges" in f][skip:]
    first = walls(all_frames[0], traj[0][2])
    base = math.degrees(cmath.phase(first) / 4) if first else 0.0
    out = []
    for k in range(start, min(len(all_frames), len(traj)), step):
        m = walls(all_frames[k], traj[k][2])
        if m is not None and abs(m) > 0.5:
            d = math.degrees(cmath.phase(m) / 4) - base
            out.append((d + 45) % 90 - 45)
    print(f"{statistics.median(out):.1f}" if out else "nan")


if __name__ == "__main__":
    main()
