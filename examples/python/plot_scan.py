"""Draws one scan of a recording and the curves isoline finds in it.

    python examples/python/plot_scan.py RECORDING [--frame N] [-o scan.png]

RECORDING is a ROS 2 bag (.mcap), a CARMEN log (.log, .clf, gzip or not) or an NDJSON
frame stream, e.g. fixtures/room-laser-80.mcap. The returns are grey dots, the curves
blue (closed) or black (open walls, the free side on their left), the sensor a red
triangle, and the returns no curve explains orange crosses.
"""

import argparse
import itertools
from pathlib import Path

import isoline


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("recording")
    ap.add_argument("--frame", type=int, default=0, help="which frame of the recording (0-based)")
    ap.add_argument("-o", "--output", help="write the figure here instead of showing it")
    args = ap.parse_args()

    import matplotlib

    if args.output:
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    frames = isoline.read_frames(args.recording)
    frame = next(itertools.islice(frames, args.frame, None), None)
    if frame is None:
        raise SystemExit(f"{args.recording} has fewer than {args.frame + 1} frames")
    result = isoline.reconstruct_frame(frame)

    fig, ax = plt.subplots(figsize=(7, 7))
    pts = frame.points
    ax.scatter(pts[:, 0], pts[:, 1], s=3, c="0.6", label=f"{len(pts)} returns")
    for curve, closed in zip(result.polylines, result.closed):
        if closed:
            curve = list(curve) + [curve[0]]
        xs, ys = zip(*curve)
        ax.plot(xs, ys, "-", lw=1.5, color="tab:blue" if closed else "black")
    ax.plot([], [], "-", color="black", label=f"{len(result.polylines)} curves")
    if len(result.features):
        f = result.features
        ax.scatter(f[:, 0], f[:, 1], marker="x", color="tab:orange", label="unexplained")
    if frame.is_scan:
        ax.plot([0], [0], "^", color="tab:red", label="sensor")
    ax.set_aspect("equal")
    ax.set_title(
        f"{Path(args.recording).name} frame {frame.frame}: "
        f"{100 * result.stats['explained']:.0f}% of returns explained"
    )
    ax.legend(loc="lower right", fontsize=8)
    for w in result.warnings:
        print("warning:", w)
    if args.output:
        fig.savefig(args.output, dpi=120)
        print(f"wrote {args.output}")
    else:
        plt.show()


if __name__ == "__main__":
    main()
