#!/usr/bin/env python3
"""Whether a recording's input poses (wheel odometry, say) are stamped ahead of or
behind its scans: each step's turn by the input poses against the same step's turn by
a trajectory estimated from the scans (`isoline map --register --trajectory`), shifted
by whole frames. Where the two are in time the correlation peaks at lag 0; a peak at
lag +1 says the scans show a turn a frame after the input poses report it (the poses
lead the scans by about a frame period). The lag is refined by a parabola through the
peak and its neighbours and printed in frames and in seconds (by the median frame
interval). The estimated turns are pulled toward the input's by registration's prior,
so a lag found is, if anything, smaller than the truth. Summed over windows of 11
frames, longer than any lag, the turns compare in size alone (a slope of 1: the input's
turns are right in size).

Usage: pose-lag.py INPUT TRAJECTORY.tum [SKIP]
INPUT: the frames (.ndjson, .ndjson.gz) whose `pose` is the input, or the input poses
as a TUM trajectory (`isoline map --trajectory` without `--register` writes them).
SKIP: poses of INPUT before the trajectory's first.
"""
import math
import os
import statistics
import sys

import ndjson
import tum

MAX_LAG = 3


def wrap(a):
    return (a + math.pi) % (2 * math.pi) - math.pi


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    missing = [a for a in sys.argv[1:3] if not os.path.exists(a)]
    if missing:
        print(f"no {', '.join(missing)}: run ISOLINE_REAL=DIR scripts/registration.sh first",
              file=sys.stderr)
        # As the scripts that need recordings do: a quick run has nothing to do.
        sys.exit(0 if os.environ.get("QUICK") == "1" else 1)
    skip = int(sys.argv[3]) if len(sys.argv) > 3 else 0
    if sys.argv[1].endswith(".tum"):
        inputs = tum.read_stamped(sys.argv[1])[skip:]
    else:
        scans = [f for f in ndjson.frames(sys.argv[1]) if "ranges" in f][skip:]
        inputs = [(f.get("t"), f.get("pose")) for f in scans]
    traj = tum.read(sys.argv[2])
    n = min(len(inputs), len(traj))
    if n < 4 * MAX_LAG or any(t is None or p is None for t, p in inputs[:n]):
        sys.exit("pose-lag.py: needs inputs with times and poses, and a trajectory of as many")
    given = [wrap(inputs[k][1][2] - inputs[k - 1][1][2]) for k in range(1, n)]
    found = [wrap(traj[k][2] - traj[k - 1][2]) for k in range(1, n)]
    period = statistics.median(inputs[k][0] - inputs[k - 1][0] for k in range(1, n))
    print("| lag, frames | steps | correlation | estimated turn / input turn |")
    print("|---:|---:|---:|---:|")
    corr = {}
    for lag in range(-MAX_LAG, MAX_LAG + 1):
        pairs = [(given[i], found[i + lag]) for i in range(len(given)) if 0 <= i + lag < len(found)]
        gg = sum(g * g for g, _ in pairs)
        ff = sum(f * f for _, f in pairs)
        gf = sum(g * f for g, f in pairs)
        if gg == 0 or ff == 0:
            continue
        corr[lag] = gf / math.sqrt(gg * ff)
        print(f"| {lag:+d} | {len(pairs)} | {corr[lag]:.3f} | {gf / gg:.3f} |")
    if not corr:
        sys.exit("pose-lag.py: neither trajectory turns")
    best = max(corr, key=corr.get)
    lag = float(best)
    if best - 1 in corr and best + 1 in corr:
        a, b, c = corr[best - 1], corr[best], corr[best + 1]
        curve = a - 2 * b + c
        if curve < 0:
            lag += 0.5 * (a - c) / curve
    # Summed over windows longer than any lag, the turns compare in size alone.
    w = 11
    sums = [(sum(given[i:i + w]), sum(found[i:i + w])) for i in range(0, len(given) - w, w)]
    gg = sum(g * g for g, _ in sums)
    gf = sum(g * f for g, f in sums)
    ff = sum(f * f for _, f in sums)
    if gg > 0 and ff > 0:
        print(f"\nOver windows of {w} frames: estimated turn / input turn {gf / gg:.3f}, "
              f"correlation {gf / math.sqrt(gg * ff):.3f}.")
    when = f"{lag * period:+.3f} s at {period:.3f} s a frame" if period > 0 else "no times"
    print(f"Peak at {lag:+.2f} frames ({when}): "
          + ("the input poses lead the scans." if lag > 0.5 else
             "the input poses lag the scans." if lag < -0.5 else
             "the input poses and the scans agree in time to within half a frame."))


if __name__ == "__main__":
    main()
