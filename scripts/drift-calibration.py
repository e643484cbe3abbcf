#!/usr/bin/env python3
"""Whether the loop search's window holds the drift (docs/benchmarks.md, "Is the loop
window wide enough?"): for each trajectory registered without loops and its reference
(scripts/registration.sh's `NAME-register-noloops.tum` beside `NAME.ref.tum`), every
third scan paired with later scans whose path apart (along the reference) falls in
5-10, 10-20, 20-40, 40-80 and 80-160 m; each pair's heading error (the estimated turn
between the two less the reference's) against the standard deviation the pose graph
gives that chain before any loop from the drift floor alone: a keyframe edge every
KEYFRAME metres (default 0.5, `keyframe_distance`) with `drift[1] * KEYFRAME + 0.1`
degrees (default 0.5 degrees a metre: 0.35 degrees an edge), so L metres give
0.35 * sqrt(L / 0.5) degrees. The graph's own chain adds each match's covariance, so its
window is wider than this one: a share beyond three of these deviations bounds the
share of loops whose true correction lies outside the window from above.

Prints a Markdown row per trajectory and path bin: pairs, RMS heading error, its 99th
percentile, and the share of pairs beyond three deviations.

Usage: drift-calibration.py [--keyframe M] [--drift DEG_PER_M] NOLOOPS.tum...
"""
import math
import os
import sys

import tum


def reference(path):
    """The reference trajectory scripts/registration.sh writes beside `path`."""
    return path.replace("-register-noloops.tum", ".ref.tum")


def wrap(a):
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def percentile(values, q):
    values = sorted(values)
    return values[min(len(values) - 1, int(q * len(values)))]


def main():
    args = sys.argv[1:]
    keyframe, drift = 0.5, 0.5
    while args and args[0].startswith("--"):
        flag, value, args = args[0], float(args[1]), args[2:]
        if flag == "--keyframe":
            keyframe = value
        elif flag == "--drift":
            drift = value
        else:
            sys.exit(__doc__)
    if not args:
        sys.exit(__doc__)
    # Only the trajectories scripts/registration.sh has made, with their references.
    missing = [a for a in args if not (os.path.exists(a) and os.path.exists(reference(a)))]
    if missing:
        print(
            f"no trajectory or no reference for {', '.join(missing)}: "
            "run ISOLINE_REAL=DIR scripts/registration.sh first",
            file=sys.stderr,
        )
        args = [a for a in args if a not in missing]
        if not args:
            # As the scripts that need recordings do: a quick run has nothing to do.
            sys.exit(0 if os.environ.get("QUICK") == "1" else 1)
    per_edge = drift * keyframe + 0.1
    print("| trajectory | path apart | pairs | heading error RMS | 99th percentile | beyond 3 σ |")
    print("|---|---|---:|---:|---:|---:|")
    for est_path in args:
        est, ref = tum.read(est_path), tum.read(reference(est_path))
        n = min(len(est), len(ref))
        path = [0.0]
        for i in range(1, n):
            path.append(path[-1] + math.dist(ref[i][:2], ref[i - 1][:2]))
        name = est_path.rsplit("/", 1)[-1].replace("-register-noloops.tum", "")
        for lo, hi in [(5, 10), (10, 20), (20, 40), (40, 80), (80, 160)]:
            errors, beyond = [], 0
            for i in range(0, n, 3):
                picked = [j for j in range(i + 1, n) if lo <= path[j] - path[i] < hi][::5]
                for j in picked:
                    e = math.degrees(abs(wrap((est[j][2] - est[i][2]) - (ref[j][2] - ref[i][2]))))
                    errors.append(e)
                    sigma = per_edge * math.sqrt((path[j] - path[i]) / keyframe)
                    beyond += e > 3.0 * sigma
            if errors:
                rms = math.sqrt(sum(e * e for e in errors) / len(errors))
                print(
                    f"| {name} | {lo}–{hi} m | {len(errors)} | {rms:.2f}° "
                    f"| {percentile(errors, 0.99):.2f}° | {100.0 * beyond / len(errors):.1f}% |"
                )


if __name__ == "__main__":
    main()
