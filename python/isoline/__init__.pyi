"""Types of the isoline package (the extension module isoline._isoline)."""

from os import PathLike
from typing import Iterator, List, Literal, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str

Pose = Tuple[float, float, float]
# What a pose argument takes: three numbers (x, y, heading in radians), as a tuple, a
# list or a numpy array.
PoseLike = Union[Tuple[float, float, float], Sequence[float], npt.NDArray[np.float64]]
ArrayLike = npt.ArrayLike

class IsolineError(ValueError):
    """Data, parameters or a file that isoline refuses; the message says what and where."""

class Params:
    """The [mesh], [solver], [export] and [scan] tables of an isoline configuration."""

    def __init__(self, toml: str = "") -> None: ...
    @staticmethod
    def load(path: Union[str, PathLike[str]]) -> "Params": ...

class Frame:
    """One frame: points, or a laser scan's beams, with stream, number, time and pose."""

    @staticmethod
    def from_points(
        points: ArrayLike,
        *,
        origin: Optional[Tuple[float, float]] = None,
        pose: Optional[PoseLike] = None,
        t: Optional[float] = None,
        frame: int = 0,
        stream: Optional[str] = None,
        frame_id: Optional[str] = None,
    ) -> "Frame": ...
    @staticmethod
    def from_scan(
        ranges: ArrayLike,
        angle_min: float,
        angle_increment: float,
        range_min: float,
        range_max: float,
        *,
        origin: Tuple[float, float] = (0.0, 0.0),
        pose: Optional[PoseLike] = None,
        t: Optional[float] = None,
        frame: int = 0,
        stream: Optional[str] = None,
        frame_id: Optional[str] = None,
    ) -> "Frame": ...
    @property
    def stream(self) -> Optional[str]: ...
    @property
    def frame_id(self) -> Optional[str]: ...
    @property
    def frame(self) -> int: ...
    @property
    def t(self) -> Optional[float]: ...
    @property
    def pose(self) -> Optional[Pose]: ...
    @property
    def points(self) -> npt.NDArray[np.float64]: ...
    @property
    def is_scan(self) -> bool: ...
    @property
    def ranges(self) -> Optional[npt.NDArray[np.float64]]: ...
    @property
    def angles(self) -> Optional[npt.NDArray[np.float64]]: ...

class Result:
    """The curves of one frame, as the isoline binary writes them in a result record."""

    @property
    def polylines(self) -> list[npt.NDArray[np.float64]]: ...
    @property
    def closed(self) -> list[bool]: ...
    @property
    def features(self) -> npt.NDArray[np.float64]: ...
    @property
    def feature_returns(self) -> npt.NDArray[np.uint64]: ...
    @property
    def junctions(self) -> list[Tuple[Tuple[float, float], list[int]]]: ...
    @property
    def warnings(self) -> list[str]: ...
    @property
    def stats(self) -> dict: ...
    @property
    def warm_start(self) -> bool: ...
    @property
    def stream(self) -> Optional[str]: ...
    @property
    def frame(self) -> Optional[int]: ...
    @property
    def t(self) -> Optional[float]: ...
    @property
    def pose(self) -> Optional[Pose]: ...
    @property
    def registered_pose(self) -> Optional[Pose]: ...
    def to_world(self, *, close: bool = False) -> list[npt.NDArray[np.float64]]: ...
    def to_json(self) -> str: ...

class Stream:
    """A sensor's frames, each warm-started from the last, as the daemon runs a stream."""

    def __init__(
        self,
        params: Optional[Params] = None,
        *,
        warm_start: bool = True,
        accumulate: int = 0,
        accumulate_seconds: Optional[float] = None,
        max_state_bytes: int = ...,
        register: bool = False,
    ) -> None: ...
    def push(
        self,
        data: Union[Frame, ArrayLike],
        pose: Optional[PoseLike] = None,
        t: Optional[float] = None,
        frame: Optional[int] = None,
    ) -> Result: ...
    @property
    def state_bytes(self) -> int: ...

class FrameReader(Iterator[Frame]):
    def __iter__(self) -> "FrameReader": ...
    def __next__(self) -> Frame: ...
    @property
    def skipped(self) -> int: ...
    @property
    def skipped_messages(self) -> List[str]: ...

def reconstruct(points: ArrayLike, params: Optional[Params] = None) -> Result: ...
def reconstruct_scan(
    ranges: ArrayLike,
    angle_min: float,
    angle_increment: float,
    range_min: float,
    range_max: float,
    pose: Optional[PoseLike] = None,
    params: Optional[Params] = None,
) -> Result: ...
def reconstruct_frame(frame: Frame, params: Optional[Params] = None) -> Result: ...
def read_frames(
    path: Union[str, PathLike[str]],
    *,
    topics: Optional[Sequence[str]] = None,
    odometry: Optional[str] = None,
    world_frame: Optional[str] = None,
    errors: Literal["warn", "raise", "ignore"] = "warn",
    max_line_bytes: int = 16777216,
    time_increment: Optional[float] = None,
) -> FrameReader: ...
