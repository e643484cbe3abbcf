"""KISS-ICP (Vizzo et al. 2023, the `kiss-icp` package) on a recording's scans, for the
pose table's peer row: each scan's returns as points at z = 0, registered to KISS-ICP's
own voxel map, the prediction for each scan the input poses' motion since the previous
scan (the wheel odometry) instead of KISS-ICP's constant velocity, which loses track at
the CARMEN logs' turns between scans a metre apart. Its defaults otherwise, with its
range limits set to isoline's (20 m) and no de-skewing (the logs give no beam times).

Writes the trajectory (TUM, one line a scan) and the frames with their poses replaced by
it, for `isoline map` to draw and score.

Usage: kiss-icp.py IN.ndjson OUT.tum OUT.ndjson
"""
import json
import math
import sys

import numpy as np
from kiss_icp.config import KISSConfig
from kiss_icp.kiss_icp import KissICP


def se3(pose):
    x, y, th = pose
    c, s = math.cos(th), math.sin(th)
    m = np.eye(4)
    m[:2, :2] = [[c, -s], [s, c]]
    m[:2, 3] = [x, y]
    return m


def returns(frame):
    r = np.array([v if v is not None else np.nan for v in frame["ranges"]], float)
    a = frame["angle_min"] + frame["angle_increment"] * np.arange(len(r))
    ok = np.isfinite(r) & (r > frame.get("range_min", 0.0)) & (r < 20.0)
    return np.c_[r[ok] * np.cos(a[ok]), r[ok] * np.sin(a[ok]), np.zeros(ok.sum())]


def main():
    src, tum, out = sys.argv[1:4]
    frames = [json.loads(l) for l in open(src) if l.startswith("{")]
    config = KISSConfig()
    config.data.max_range = 20.0
    config.data.deskew = False
    # As KISS-ICP's own configuration loader sets it when none is given.
    config.mapping.voxel_size = config.data.max_range / 100.0
    kiss = KissICP(config)
    start = se3(frames[0]["pose"])
    last = None
    with open(tum, "w") as t, open(out, "w") as o:
        t.write("# t x y z qx qy qz qw\n")
        for f in frames:
            if last is not None:
                kiss.last_delta = np.linalg.inv(se3(last)) @ se3(f["pose"])
            last = f["pose"]
            kiss.register_frame(returns(f), np.zeros(0))
            m = start @ kiss.last_pose
            x, y, th = m[0, 3], m[1, 3], math.atan2(m[1, 0], m[0, 0])
            t.write(f"{f['t']:.6f} {x:.6f} {y:.6f} 0 0 0 {math.sin(th / 2):.9f} {math.cos(th / 2):.9f}\n")
            o.write(json.dumps({**f, "pose": [x, y, th]}) + "\n")


if __name__ == "__main__":
    main()
