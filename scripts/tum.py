"""TUM trajectories (`t x y z qx qy qz qw` a line, `#` comments), as `isoline map
--trajectory` writes them and scripts/drift-odometry.py writes references: the
scripts that score poses read them here."""
import math


def read(path):
    """The trajectory at `path` as (x, y, heading) a pose, the heading from the
    quaternion about z."""
    return [pose for _, pose in read_stamped(path)]


def read_stamped(path):
    """The trajectory at `path` as (t, (x, y, heading)) a pose."""
    poses = []
    for line in open(path):
        if line.startswith("#") or not line.strip():
            continue
        t, x, y, _, _, _, qz, qw = map(float, line.split()[:8])
        poses.append((t, (x, y, 2.0 * math.atan2(qz, qw))))
    return poses
