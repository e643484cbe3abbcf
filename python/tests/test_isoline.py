"""The Python package against the `isoline` binary: the same frames give the same
curves, a Stream takes the daemon's warm/cold decisions, and nothing a caller passes
crashes the interpreter.

The binary is `$ISOLINE_BIN`, else `target/debug/isoline` (built when missing). The real
recordings are read from `$ISOLINE_REAL` when it is set (CARMEN `*.log.gz`, bags
`*.mcap`); without it those tests are skipped, and the shipped fixtures cover the same
paths.
"""

import json
import gzip
import math
import os
import subprocess
import sys
import threading
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

import isoline

ROOT = Path(__file__).resolve().parents[2]
FIXTURES = ROOT / "fixtures"


@pytest.fixture(scope="session")
def binary():
    path = os.environ.get("ISOLINE_BIN")
    if path:
        return Path(path)
    path = ROOT / "target" / "debug" / "isoline"
    if not path.exists():
        subprocess.run(["cargo", "build", "--bin", "isoline"], cwd=ROOT, check=True)
    return path


def records(path):
    return [json.loads(line) for line in Path(path).read_text().splitlines() if line.strip()]


def binary_records(binary, tmp_path, input_path, *args):
    out = tmp_path / "out.ndjson"
    subprocess.run(
        [str(binary), "reconstruct", str(input_path), "-o", str(out), *args],
        check=True,
        capture_output=True,
    )
    return records(out)


def assert_same_curves(result, record, tol=1e-9):
    """The same curves within `tol`: the Python API and the binary run the same code,
    so only the last bits of the floating-point numbers written as JSON may differ."""
    theirs = record.get("polylines", [])
    assert len(result.polylines) == len(theirs)
    assert result.closed == [p["closed"] for p in theirs]
    for ours, p in zip(result.polylines, theirs):
        np.testing.assert_allclose(ours, np.array(p["points"]).reshape(-1, 2), atol=tol)
    assert result.warnings == record.get("warnings", [])


def real(name):
    folder = os.environ.get("ISOLINE_REAL")
    if not folder or not (Path(folder) / name).exists():
        pytest.skip(f"{name}: set ISOLINE_REAL to the folder of the real recordings")
    return Path(folder) / name


# --- one frame -------------------------------------------------------------------


def test_a_circle_is_one_closed_counter_clockwise_curve():
    a = np.linspace(0, 2 * np.pi, 300, endpoint=False)
    r = isoline.reconstruct(np.c_[0.5 + 0.4 * np.cos(a), 0.5 + 0.4 * np.sin(a)])
    assert r.closed == [True]
    (curve,) = r.polylines
    assert curve.dtype == np.float64 and curve.shape[1] == 2
    radius = np.hypot(curve[:, 0] - 0.5, curve[:, 1] - 0.5)
    # Clean samples: the curve lies within a few hmin (D / 1000 each) of the circle.
    assert np.abs(radius - 0.4).max() < 5 * math.hypot(0.8, 0.8) / 1000
    x, y = curve[:, 0], curve[:, 1]
    assert 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) > 0
    assert r.stats["points"] == 300 and not r.warm_start


@pytest.mark.parametrize("name", ["star-600-n001.ndjson", "two-circles-600-n001.ndjson"])
def test_points_give_the_binarys_curves(binary, tmp_path, name):
    (record,) = binary_records(binary, tmp_path, FIXTURES / name)
    (frame,) = list(isoline.read_frames(FIXTURES / name))
    assert_same_curves(isoline.reconstruct(frame.points), record)
    assert_same_curves(isoline.reconstruct_frame(frame), record)


def test_a_point_file_gives_the_binarys_curves(binary, tmp_path):
    (record,) = binary_records(binary, tmp_path, FIXTURES / "circle-500.xy")
    points = np.loadtxt(FIXTURES / "circle-500.xy")
    assert_same_curves(isoline.reconstruct(points), record)


def test_scans_give_the_binarys_curves(binary, tmp_path):
    stream = FIXTURES / "clutter-hokuyo-20.ndjson"
    theirs = binary_records(binary, tmp_path, stream, "--frame", "3")
    (record,) = theirs
    line = json.loads(stream.read_text().splitlines()[3])
    ranges = np.array([np.nan if r is None else r for r in line["ranges"]])
    r = isoline.reconstruct_scan(
        ranges,
        line["angle_min"],
        line["angle_increment"],
        line.get("range_min", 0.0),
        line["range_max"],
        pose=tuple(line["pose"]),
    )
    assert_same_curves(r, record)
    assert r.features.shape == (len(record["features"]), 2)
    assert r.pose == tuple(line["pose"])
    # The world placement is the pose's rigid motion of the frame's curves.
    x, y, th = line["pose"]
    for local, world in zip(r.polylines, r.to_world()):
        c, s = math.cos(th), math.sin(th)
        np.testing.assert_allclose(world[:, 0], x + c * local[:, 0] - s * local[:, 1])
        np.testing.assert_allclose(world[:, 1], y + s * local[:, 0] + c * local[:, 1])


def test_a_bag_reads_as_the_binary_reads_it(binary, tmp_path):
    bag = FIXTURES / "room-laser-80.mcap"
    theirs = binary_records(binary, tmp_path, bag)
    frames = list(isoline.read_frames(bag))
    assert len(frames) == len(theirs) == 80
    for frame, record in list(zip(frames, theirs))[::20]:
        assert (frame.stream, frame.frame) == (record["stream"], record["frame"])
        assert_same_curves(isoline.reconstruct_frame(frame), record)
    # The scans' header frame id, where a ROS user looks for it.
    assert {f.frame_id for f in frames} == {"laser"}


def test_a_frame_id_is_kept_through_ndjson_and_given_to_constructors(binary, tmp_path):
    bag = FIXTURES / "room-laser-80.mcap"
    out = tmp_path / "frames.ndjson"
    subprocess.run(
        [binary, "convert", str(bag), "--odometry", "/odom", "-o", str(out)],
        check=True,
        capture_output=True,
    )
    first = json.loads(out.read_text().splitlines()[0])
    assert first["frame_id"] == "laser"
    (frame,) = list(isoline.read_frames(out))[:1]
    assert frame.frame_id == "laser"
    made = isoline.Frame.from_scan([1.0, 1.0], 0.0, 0.1, 0.1, 10.0, frame_id="base_laser")
    assert made.frame_id == "base_laser"
    assert isoline.Frame.from_points(np.zeros((3, 2))).frame_id is None


def test_a_turning_sweep_is_read_corrected_by_its_timing(tmp_path):
    # A sensor at the origin turning at 1 rad/s before a wall at x = 3: 201 beams over
    # 100 degrees, 1 ms apart, so the last is taken 0.2 rad later than the first.
    def record(t, timed):
        a0, inc = math.radians(-50), math.radians(0.5)
        ranges = [3.0 / math.cos(t + 1e-3 * i + a0 + i * inc) for i in range(201)]
        rec = {"stream": "s", "frame": round(10 * t), "t": t, "pose": [0, 0, t],
               "ranges": ranges, "angle_min": a0, "angle_increment": inc, "range_max": 20}
        if timed:
            rec["time_increment"] = 1e-3
        return json.dumps(rec)

    def off_wall(frame):
        x, y, h = frame.pose
        p = frame.points
        return np.abs(x + np.cos(h) * p[:, 0] - np.sin(h) * p[:, 1] - 3.0).max()

    timed, untimed = tmp_path / "timed.ndjson", tmp_path / "untimed.ndjson"
    timed.write_text(record(0.0, True) + "\n" + record(0.1, True) + "\n")
    untimed.write_text(record(0.0, False) + "\n" + record(0.1, False) + "\n")
    # The first frame has no motion before it: as it came, its far beams 0.2 rad off.
    first, second = list(isoline.read_frames(timed))
    assert off_wall(first) > 0.1
    assert off_wall(second) < 1e-9
    assert off_wall(list(isoline.read_frames(untimed))[1]) > 0.1
    assert off_wall(list(isoline.read_frames(untimed, time_increment=1e-3))[1]) < 1e-9
    with pytest.raises(ValueError):
        isoline.read_frames(untimed, time_increment=-1.0)


def test_a_registered_stream_without_poses_corrects_its_sweeps(tmp_path):
    # A 360-beam scanner turning on the spot at 1 rad/s in a 6 m x 4 m room, no pose
    # given: its 100 ms sweep turns 0.1 rad between its first beam and its last.
    def ranges(t):
        out = []
        for i in range(360):
            b = (t + i / 3600.0) + math.radians(-180 + i)
            c, s = math.cos(b), math.sin(b)
            hits = [w / d for w, d in ((3.5, c), (-2.5, c), (2.3, s), (-1.7, s)) if w * d > 0]
            out.append(min(hits))
        return out

    def off_walls(timed):
        """How far the last frame's curves lie from the room's walls, in the frame's
        coordinates at its first beam (the sensor at the origin, turned by t)."""
        stream = isoline.Stream(register=True)
        for k in range(20):
            t = 0.1 * k
            rec = {"frame": k, "t": t, "ranges": ranges(t), "angle_min": -math.pi,
                   "angle_increment": math.radians(1), "range_max": 20}
            if timed:
                rec["time_increment"] = 0.1 / 360
            path = tmp_path / f"f{k}.ndjson"
            path.write_text(json.dumps(rec) + "\n")
            (frame,) = list(isoline.read_frames(path))
            result = stream.push(frame)
        c, s = math.cos(t), math.sin(t)
        worst = 0.0
        for curve in result.polylines:
            x = c * curve[:, 0] - s * curve[:, 1]
            y = s * curve[:, 0] + c * curve[:, 1]
            d = np.minimum(np.minimum(abs(x - 3.5), abs(x + 2.5)), np.minimum(abs(y - 2.3), abs(y + 1.7)))
            worst = max(worst, float(d.max()))
        return worst

    # The scan handed on to the reconstruction is the corrected one: its curves lie on
    # the walls to within the curves' accuracy; read as taken at once, the sweep's last
    # beams are 0.1 rad round from its first, up to 0.3 m off on the far walls.
    assert off_walls(True) < 0.02
    assert off_walls(False) > 0.1


def test_the_result_record_is_the_binarys(binary, tmp_path):
    (record,) = binary_records(binary, tmp_path, FIXTURES / "c-600-n001.ndjson")
    (frame,) = list(isoline.read_frames(FIXTURES / "c-600-n001.ndjson"))
    ours = json.loads(isoline.reconstruct_frame(frame).to_json())
    timings = ("ms",)
    for key in set(ours) | set(record):
        if key == "stats":
            for k in set(ours[key]) | set(record[key]):
                if k not in timings:
                    assert ours[key].get(k) == pytest.approx(record[key].get(k)), k
        elif key != "polylines":
            assert ours.get(key) == record.get(key), key


def test_params_reach_the_method():
    points = np.loadtxt(FIXTURES / "circle-500.xy")
    fine = isoline.reconstruct(points)
    coarse = isoline.reconstruct(points, params=isoline.Params("[export]\nsimplify = 0.01\n"))
    assert len(coarse.polylines[0]) < len(fine.polylines[0]) / 4
    with pytest.raises(ValueError, match="mesh.hmin"):
        isoline.Params("[mesh]\nhmin = -1\n")
    with pytest.raises(ValueError, match="hmni"):
        isoline.Params("[mesh]\nhmni = 1\n")
    assert isoline.Params.load(ROOT / "config" / "example.toml")


# --- refusals, never crashes -------------------------------------------------------


@pytest.mark.parametrize(
    "points, message",
    [
        (np.zeros((5, 3)), "expected \\(N, 2\\)"),
        (np.zeros(10), "expected \\(N, 2\\)"),
        (np.zeros((2, 2, 2)), "expected \\(N, 2\\)"),
        ([[0.0, 0.0], [1.0, math.nan], [2.0, 2.0]], "point 1"),
        ([[0.0, 0.0], [math.inf, 1.0]], "point 1"),
        (np.zeros((0, 2)), "no points|empty"),
        (np.zeros((50, 2)), "coincide"),
        ("not points", "not an array"),
        ([[0, 0], [1]], "not an array"),
        (None, "expected \\(N, 2\\)"),
    ],
)
def test_bad_points_raise_value_error(points, message):
    with pytest.raises(ValueError, match=message):
        isoline.reconstruct(points)


def test_bad_scans_raise_value_error():
    with pytest.raises(ValueError):
        isoline.reconstruct_scan(np.ones((3, 3)), 0.0, 0.01, 0.0, 10.0)
    with pytest.raises(ValueError):
        isoline.reconstruct_scan(np.ones(100), math.nan, 0.01, 0.0, 10.0)
    with pytest.raises(ValueError):
        isoline.reconstruct_scan(np.ones(100), 0.0, 0.01, 0.0, 10.0, pose=(0.0, math.inf, 0.0))
    with pytest.raises(ValueError):
        isoline.reconstruct_scan(np.ones(70_000), 0.0, 1e-5, 0.0, 10.0)
    # No return at all is a frame without data, not a crash.
    with pytest.raises(ValueError):
        isoline.reconstruct_scan(np.full(100, np.nan), 0.0, 0.01, 0.0, 10.0)


def test_bad_files_and_options_raise(tmp_path):
    with pytest.raises(OSError):
        isoline.read_frames(tmp_path / "missing.ndjson")
    bad = tmp_path / "bad.ndjson"
    good = json.dumps({"frame": 0, "points": [[0, 0], [1, 0], [1, 1], [0, 1]] * 10})
    bad.write_text(good + "\n{\"frame\": 1, \"points\": 7}\n" + good.replace('"frame": 0', '"frame": 2') + "\n")
    with pytest.warns(UserWarning, match="line 2"):
        frames = list(isoline.read_frames(bad))
    assert [f.frame for f in frames] == [0, 2]
    with pytest.raises(isoline.IsolineError, match="line 2"):
        list(isoline.read_frames(bad, errors="raise"))
    assert len(list(isoline.read_frames(bad, errors="ignore"))) == 2
    with pytest.raises(ValueError):
        isoline.read_frames(bad, errors="sometimes")
    notes = tmp_path / "notes.log"
    notes.write_text("PARAM robot x\nthis is not a log\n")
    with pytest.raises(ValueError):
        list(isoline.read_frames(notes))
    with pytest.raises(ValueError):
        isoline.Stream(accumulate=1000)


# --- streams -------------------------------------------------------------------------


def daemon_records(binary, tmp_path, input_path, accumulate=0, register=False):
    out = tmp_path / "daemon.ndjson"
    config = tmp_path / "run.toml"
    config.write_text(
        f"""
[input]
path = {json.dumps(str(input_path))}
replay = "fast"

[output]
path = {json.dumps(str(out))}

[pipeline]
policy = "block"
warm_start = true
accumulate = {accumulate}
register = {"true" if register else "false"}
"""
    )
    subprocess.run([str(binary), "run", "-c", str(config)], check=True, capture_output=True)
    return sorted(records(out), key=lambda r: (r.get("stream", ""), r["frame"]))


def decisions(record):
    s = record["stats"]
    return (record["frame"], s["warm_start"], s["start"], s.get("cold_fallback", False))


def assert_stream_matches_daemon(binary, tmp_path, path, accumulate=0, frames=None):
    theirs = daemon_records(binary, tmp_path, path, accumulate)
    by_stream = {}
    for f in isoline.read_frames(path, errors="ignore"):
        by_stream.setdefault(f.stream, []).append(f)
    ours = []
    for name, fs in sorted(by_stream.items(), key=lambda kv: kv[0] or ""):
        stream = isoline.Stream(accumulate=accumulate)
        ours += [json.loads(stream.push(f).to_json()) for f in fs]
    ours = [r for r in ours if frames is None or r["frame"] < frames]
    theirs = [r for r in theirs if "error" not in r and (frames is None or r["frame"] < frames)]
    assert len(ours) == len(theirs)
    assert [decisions(r) for r in ours] == [decisions(r) for r in theirs]
    # Same decisions from the same state: the same curves.
    for a, b in zip(ours, theirs):
        assert len(a.get("polylines", [])) == len(b.get("polylines", [])), a["frame"]
    return ours


def test_a_stream_of_points_takes_the_daemons_decisions(binary, tmp_path):
    ours = assert_stream_matches_daemon(binary, tmp_path, FIXTURES / "ellipse-stream-20.ndjson")
    # A slowly changing ellipse: every frame after the first starts warm.
    assert [r["stats"]["warm_start"] for r in ours] == [False] + [True] * (len(ours) - 1)


def test_a_stream_of_scans_takes_the_daemons_decisions(binary, tmp_path):
    assert_stream_matches_daemon(binary, tmp_path, FIXTURES / "clutter-hokuyo-20.ndjson")


def test_a_refined_stream_takes_the_daemons_decisions(binary, tmp_path):
    ours = assert_stream_matches_daemon(
        binary, tmp_path, FIXTURES / "clutter-hokuyo-20.ndjson", accumulate=5
    )
    assert any(r["stats"]["start"] in ("fused", "fallback") for r in ours)


def test_a_stream_over_a_real_log_takes_the_daemons_decisions(binary, tmp_path):
    log = real("aces-corrected.log.gz")
    # The first 120 frames: the whole log takes minutes in a debug build.
    head = tmp_path / "aces-head.log"
    lines, lasers = [], 0
    import gzip

    with gzip.open(log, "rt") as f:
        for line in f:
            lines.append(line)
            lasers += line.startswith(("FLASER", "ROBOTLASER1"))
            if lasers == 120:
                break
    head.write_text("".join(lines))
    ours = assert_stream_matches_daemon(binary, tmp_path, head)
    assert len(ours) == 120


def test_a_registered_stream_gives_the_daemons_poses(binary, tmp_path):
    path = FIXTURES / "clutter-hokuyo-20.ndjson"
    theirs = daemon_records(binary, tmp_path, path, accumulate=5, register=True)
    stream = isoline.Stream(accumulate=5, register=True)
    ours = [stream.push(f) for f in isoline.read_frames(path)]
    assert len(ours) == len(theirs) == 20
    for a, b in zip(ours, theirs):
        # The same registration of the same scans: the same estimate, to rounding.
        assert a.registered_pose is not None
        assert np.allclose(a.registered_pose, b["registered_pose"], atol=1e-9)
        assert a.pose == tuple(b["pose"])
    # The shipped stream's poses are the simulator's: the estimate stays on them.
    err = max(math.dist(r.registered_pose[:2], r.pose[:2]) for r in ours)
    assert err < 0.02, err
    assert isoline.Stream().push(next(iter(isoline.read_frames(path)))).registered_pose is None


def test_a_restarted_stream_starts_cold():
    a = np.linspace(0, 2 * np.pi, 240, endpoint=False)
    ring = np.c_[np.cos(a), np.sin(a)]
    stream = isoline.Stream()
    assert [stream.push(ring * (1 + 0.01 * i)).warm_start for i in range(3)] == [False, True, True]
    assert not stream.push(ring, frame=0).warm_start
    assert stream.push(ring * 1.01).frame == 1
    cold = isoline.Stream(warm_start=False)
    assert not any(cold.push(ring).warm_start for _ in range(3))


def test_the_gil_is_released_while_reconstructing():
    a = np.linspace(0, 2 * np.pi, 4000, endpoint=False)
    points = np.c_[np.cos(a), np.sin(a)] + np.random.default_rng(1).normal(0, 0.01, (4000, 2))
    ticks = []
    done = threading.Event()

    def tick():
        while not done.is_set():
            ticks.append(time.perf_counter())
            time.sleep(0.001)

    t = threading.Thread(target=tick)
    t.start()
    start = time.perf_counter()
    isoline.reconstruct(points)
    end = time.perf_counter()
    done.set()
    t.join()
    during = [x for x in ticks if start < x < end]
    # A held GIL would stop the ticker for the whole call; released, it ticks about
    # every millisecond (at least once every 50 ms on a loaded machine).
    assert len(during) >= (end - start) / 0.05, (len(during), end - start)


# --- the package around the module --------------------------------------------------


def test_the_stubs_name_what_the_module_has():
    import ast

    stub = ast.parse((Path(isoline.__file__).parent / "__init__.pyi").read_text())
    classes = {n.name: n for n in stub.body if isinstance(n, ast.ClassDef)}
    functions = {n.name for n in stub.body if isinstance(n, ast.FunctionDef)}
    assert set(isoline.__all__) - {"__version__"} == set(classes) | functions
    for name, node in classes.items():
        members = {m.name for m in node.body if isinstance(m, ast.FunctionDef)}
        for member in members - {"__init__"}:
            assert hasattr(getattr(isoline, name), member), f"{name}.{member}"
    for name in functions:
        assert getattr(isoline, name).__doc__, name


def test_the_plot_example_draws_a_scan(tmp_path):
    pytest.importorskip("matplotlib")
    out = tmp_path / "scan.png"
    subprocess.run(
        [
            sys.executable,
            str(ROOT / "examples" / "python" / "plot_scan.py"),
            str(FIXTURES / "room-laser-80.mcap"),
            "--frame",
            "10",
            "-o",
            str(out),
        ],
        check=True,
        capture_output=True,
    )
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out.stat().st_size > 10_000


def test_the_snippets_of_docs_python_md_run(monkeypatch):
    import re

    page = (ROOT / "docs" / "python.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", page, re.S)
    assert len(blocks) >= 2
    monkeypatch.chdir(ROOT)
    # In order, in one namespace, as a reader pastes them into one session.
    namespace = {}
    for block in blocks:
        exec(compile(block, "docs/python.md", "exec"), namespace)
    assert namespace["r"].polylines and namespace["world"]


# --- bad input: what a careless user or an attacker passes ---------------------------


def test_arrays_that_claim_more_rows_than_memory_raise_not_abort():
    # A view of two numbers that claims 10^11 rows: copying it would need 1.6 TB.
    huge = np.broadcast_to(np.array([1.0, 2.0]), (10**11, 2))
    with pytest.raises(MemoryError):
        isoline.reconstruct(huge)
    # A scan holds at most 65,536 beams: refused before the copy.
    ranges = np.broadcast_to(np.array(1.0), (10**11,))
    with pytest.raises(ValueError, match="at most 65536"):
        isoline.reconstruct_scan(ranges, 0.0, 1e-6, 0.0, 10.0)


def test_push_refuses_what_the_constructors_refuse():
    stream = isoline.Stream()
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]] * 10, dtype=float)
    with pytest.raises(isoline.IsolineError, match="pose"):
        stream.push(square, pose=(math.nan, 0.0, 0.0))
    with pytest.raises(isoline.IsolineError, match="t = inf"):
        stream.push(square, t=math.inf)
    frame = isoline.Frame.from_points(square)
    with pytest.raises(isoline.IsolineError, match="pose"):
        stream.push(frame, pose=(0.0, math.inf, 0.0))
    # The stream is unharmed.
    assert stream.push(square, pose=(0.0, 0.0, 0.0), t=1.0).pose == (0.0, 0.0, 0.0)


def peak_rss_mib():
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def test_ndjson_frames_stream_with_bounded_read_ahead(tmp_path):
    # 400 MB of frames in 0.6 MB of gzip: held, they took gigabytes before the first
    # frame came; streamed, the first comes at once.
    bomb = tmp_path / "bomb.ndjson.gz"
    line = (json.dumps({"frame": 0, "points": [[0, 0], [1, 0], [1, 1], [0, 1]] * 3}) + "\n").encode()
    block = line * (1 << 20 // len(line))
    with gzip.open(bomb, "wb", compresslevel=1) as f:
        for _ in range(400):
            f.write(block)
    before = peak_rss_mib()
    start = time.monotonic()
    reader = isoline.read_frames(bomb)
    first = next(reader)
    assert len(first.points) == 12
    del reader
    assert time.monotonic() - start < 5.0
    assert peak_rss_mib() - before < 100


def test_bad_lines_give_one_warning_with_a_count(tmp_path):
    bad = tmp_path / "bad.ndjson"
    good = json.dumps({"frame": 0, "points": [[0, 0], [1, 0], [1, 1], [0, 1]] * 10})
    bad.write_text(good + "\n" + "{\"frame\": 1, \"points\": 7}\n" * 200_000)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        reader = isoline.read_frames(bad)
        frames = list(reader)
    assert len(frames) == 1
    assert len(caught) == 1
    assert "200000 frame(s)" in str(caught[0].message)
    assert reader.skipped == 200_000
    assert len(reader.skipped_messages) == 100
    assert "line 2" in reader.skipped_messages[0]


def test_the_ndjson_line_cap_is_a_setting(tmp_path):
    path = tmp_path / "long.ndjson"
    path.write_text(json.dumps({"frame": 0, "points": [[0, 0], [1, 0], [1, 1], [0, 1]] * 100}) + "\n")
    with pytest.raises(isoline.IsolineError, match="longer than 100 bytes"):
        list(isoline.read_frames(path, errors="raise", max_line_bytes=100))
    assert len(list(isoline.read_frames(path, max_line_bytes=1 << 20))) == 1


# --- poses as numpy users pass them ---------------------------------------------------


def room_scan():
    angles = np.linspace(-math.pi / 2, math.pi / 2, 181)
    # A wall 2 m ahead: range 2 / cos(bearing), beyond 8 m none.
    ranges = np.where(np.abs(angles) < 1.3, 2.0 / np.cos(angles), np.nan)
    return ranges, float(angles[0]), float(angles[1] - angles[0])


@pytest.mark.parametrize("pose", [(1.0, 2.0, 0.5), [1.0, 2.0, 0.5], np.array([1.0, 2.0, 0.5])])
def test_a_pose_is_any_three_numbers(pose):
    ranges, a0, step = room_scan()
    r = isoline.reconstruct_scan(ranges, a0, step, 0.0, 8.0, pose=pose)
    assert r.pose == (1.0, 2.0, 0.5)
    f = isoline.Frame.from_scan(ranges, a0, step, 0.0, 8.0, pose=pose)
    assert f.pose == (1.0, 2.0, 0.5)
    assert isoline.Stream().push(f, pose=pose).pose == (1.0, 2.0, 0.5)


def test_bad_poses_say_what_a_pose_is():
    ranges, a0, step = room_scan()
    with pytest.raises(TypeError, match="three numbers"):
        isoline.reconstruct_scan(ranges, a0, step, 0.0, 8.0, pose=(1.0, 2.0))
    with pytest.raises(TypeError, match="radians"):
        isoline.reconstruct_scan(ranges, a0, step, 0.0, 8.0, pose="north")
    with pytest.raises(isoline.IsolineError, match="not finite"):
        isoline.reconstruct_scan(ranges, a0, step, 0.0, 8.0, pose=(0.0, math.nan, 0.0))


def test_a_heading_in_degrees_is_warned_of_once():
    # Once a process: in a fresh one, so that no other test has taken it.
    code = (
        "import warnings, numpy as np, isoline\n"
        "warnings.simplefilter('always')\n"
        "a = np.linspace(-1.5, 1.5, 181)\n"
        "r = 2.0 / np.cos(a)\n"
        "for th in (0.5, 90.0, 180.0):\n"
        "    isoline.reconstruct_scan(r, -1.5, 3.0 / 180, 0.0, 8.0, pose=(0.0, 0.0, th))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stderr.count("radians (degrees?)") == 1, out.stderr


def test_a_scan_frame_gives_back_its_beams_and_world_curves_close():
    ranges, a0, step = room_scan()
    f = isoline.Frame.from_scan(ranges, a0, step, 0.0, 8.0, pose=(0.0, 0.0, 0.0))
    assert len(f.ranges) == len(f.angles) == 181
    assert np.isnan(f.ranges[0]) and abs(f.ranges[90] - 2.0) < 1e-12
    assert abs(f.angles[0] - a0) < 1e-12
    assert isoline.Frame.from_points(np.random.default_rng(1).random((50, 2))).ranges is None
    # A closed curve in the world repeats its first point with close=True.
    a = np.linspace(0, 2 * math.pi, 400, endpoint=False)
    circle = np.c_[np.cos(a), np.sin(a)]
    r = isoline.Stream().push(circle, pose=(5.0, 0.0, 0.0))
    assert r.closed == [True]
    opened, = r.to_world()
    closed, = r.to_world(close=True)
    assert len(closed) == len(opened) + 1
    np.testing.assert_allclose(closed[0], closed[-1])
    assert abs(opened[:, 0].mean() - 5.0) < 0.05


def test_refinement_without_poses_is_said_once():
    ranges, a0, step = room_scan()
    stream = isoline.Stream(accumulate=5)
    with pytest.warns(UserWarning, match="no"):
        stream.push(isoline.Frame.from_scan(ranges, a0, step, 0.0, 8.0))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        stream.push(isoline.Frame.from_scan(ranges, a0, step, 0.0, 8.0, frame=1))


def test_shape_errors_are_isoline_errors():
    with pytest.raises(isoline.IsolineError, match="expected \\(N, 2\\)"):
        isoline.reconstruct(np.ones((5, 3)))
