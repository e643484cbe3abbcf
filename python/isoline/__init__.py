"""isoline: smooth curves from noisy 2D points and laser scans.

The level-set curve reconstruction of Claisse & Frey (2009), in Rust, on numpy arrays:

>>> import numpy as np, isoline
>>> a = np.linspace(0, 2 * np.pi, 300, endpoint=False)
>>> r = isoline.reconstruct(np.c_[np.cos(a), np.sin(a)])
>>> len(r.polylines), r.closed
(1, [True])

- ``reconstruct(points)`` and ``reconstruct_scan(ranges, ...)``: one frame.
- ``Stream``: a sensor's frames one after the other, each warm-started from the last,
  optionally refined over a window of frames (as the ``isoline run`` daemon does).
- ``read_frames(path)``: the frames of a ROS 2 bag, a CARMEN log, an NDJSON stream.

Every call releases the GIL while the method runs. Data or parameters isoline refuses
raise ``ValueError`` (``IsolineError``); files that cannot be read raise ``OSError``.
See docs/python.md.
"""

from ._isoline import (
    Frame,
    FrameReader,
    IsolineError,
    Params,
    Result,
    Stream,
    __version__,
    read_frames,
    reconstruct,
    reconstruct_frame,
    reconstruct_scan,
)

__all__ = [
    "Frame",
    "FrameReader",
    "IsolineError",
    "Params",
    "Result",
    "Stream",
    "__version__",
    "read_frames",
    "reconstruct",
    "reconstruct_frame",
    "reconstruct_scan",
]
