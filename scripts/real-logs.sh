#!/usr/bin/env bash
# The real-recording table of docs/benchmarks.md: each CARMEN log (*.log.gz, converted
# as published), NDJSON beam stream (*.ndjson.gz) and ROS 2 bag (*.mcap, its scans posed
# by the Odometry topic $ODOMETRY, default /odom) in $ISOLINE_REAL is unpacked into
# target/real-logs/ and
# replayed through the daemon as fast as it goes, single-frame (cold; warm: the same
# frames with warm starts on and their poses removed; posed: warm with the poses) and
# refined over 10 frames (`accumulate = 10`), with scripts/split_and_merge.py on the
# same frames; each run is scored by `isoline eval --frames` (no truth: returns within
# 5 cm of a curve, curve within 10 cm of a return, curve in the free space the beams
# swept, mean distance from explained returns to the curve and from the next scan's
# returns ("next cm", held out), closed curves, phantom pieces within 1 m of the
# sensor, frames whose curves cross a beam more than 5 cm / the frame's accuracy bound
# 3 sigma + 2 hmin short of its return), and against the cold
# run frame by frame (frames 5+ points worse). Medians over frames. Then, from the
# daemon's summaries: frames/s, the process's CPU per frame and the stages' split.
# Usage: ISOLINE_REAL=DIR scripts/real-logs.sh
set -euo pipefail
. "$(dirname "$0")/lib.sh"
need_recordings
dir=target/real-logs
mkdir -p "$dir"
for gz in "$real"/*.gz "$real"/*.mcap; do
  [ -e "$gz" ] || continue
  name=$(basename "$gz" .gz)
  case $name in
    # CARMEN logs are read as published (gzip, `.log`).
    *.log) name=${name%.log}; "$bin" convert "$gz" -o "$dir/$name.ndjson" 2>/dev/null ;;
    *.ndjson) name=${name%.ndjson}; zcat "$gz" > "$dir/$name.ndjson" ;;
    # ROS 2 bags: every LaserScan topic, posed by the Odometry on $ODOMETRY (/odom).
    *.mcap) name=${name%.mcap}
      "$bin" convert "$gz" --odometry "${ODOMETRY:-/odom}" -o "$dir/$name.ndjson" 2>/dev/null ;;
    *) continue ;;
  esac
  frames=$dir/$name.ndjson
  [ "$quick" = 1 ] && { head -n 20 "$frames" > "$frames.quick"; mv "$frames.quick" "$frames"; }
  # The same frames without their poses, for warm starts that cannot move the last
  # frame's level set by the sensor's motion.
  python3 -c 'import json,sys
for l in open(sys.argv[1]):
    v = json.loads(l); v.pop("pose", None); print(json.dumps(v))' "$frames" > "$dir/$name.nopose.ndjson"
  for run in cold warm posed refined; do
    input=$name.ndjson
    case $run in
      cold) pipeline='warm_start = false' ;;
      warm) pipeline='warm_start = true'; input=$name.nopose.ndjson ;;
      posed) pipeline='warm_start = true' ;;
      refined) pipeline='accumulate = 10' ;;
    esac
    printf '[input]\npath = "%s"\nreplay = "fast"\n[output]\npath = "%s"\n[pipeline]\n%s\n' \
      "$input" "$name.$run.out.ndjson" "$pipeline" > "$dir/$name.$run.toml"
    (cd "$dir" && "$OLDPWD/$bin" run -c "$name.$run.toml" 2> "$name.$run.log")
    "$bin" eval "$dir/$name.$run.out.ndjson" --frames "$frames" > "$dir/$name.$run.eval.json"
  done
  python3 scripts/split_and_merge.py "$frames" "$dir/$name.sam.out.ndjson" --sigma 0.01 > "$dir/$name.sam.log" 2>&1
  "$bin" eval "$dir/$name.sam.out.ndjson" --frames "$frames" > "$dir/$name.sam.eval.json"
  python3 - "$dir" "$name" <<'PY'
import json, re, statistics, sys
d, name = sys.argv[1:]
ev = lambda r: json.load(open(f"{d}/{name}.{r}.eval.json"))
cold = {f["frame"]: f for f in ev("cold")["frames"]}
def sam_ms():
    m = re.findall(r"median ([0-9.]+) ms a frame", open(f"{d}/{name}.sam.log").read())
    return float(m[-1]) if m else float("nan")
def fps(r):
    try:
        m = re.findall(r"([0-9.]+) frames/s", open(f"{d}/{name}.{r}.log").read())
        return m[-1] if m else "-"
    except FileNotFoundError:
        return "-"
def crossed(e):
    past = e["frames_crossing_beams_past_bound"]
    return f"{e['frames_crossing_beams']} / {'-' if past is None else past}"
print(f"{name}: {len(cold)} frames")
print(f"  {'run':8s} {'5cm':>6s} {'10cm':>6s} {'free':>7s} {'mean cm':>8s} {'next cm':>8s} {'worse':>6s} {'closed':>6s} {'phantom':>7s} {'crossed':>9s} {'ms':>6s} {'fps':>7s}")
for r in ["cold", "warm", "posed", "refined", "sam"]:
    e = ev(r)
    worse = sum(1 for f in e["frames"] if f["frame"] in cold and f["returns_explained"] < cold[f["frame"]]["returns_explained"] - 0.05)
    ms = sam_ms() if r == "sam" else e.get("ms")
    print(f"  {r:8s} {e['returns_explained']:6.3f} {e['curve_on_data']:6.3f} {e['free_space_share']:7.4f} "
          f"{100 * e['mean_distance']:8.2f} {100 * (e['held_out_distance'] or float('nan')):8.3f} {worse:6d} {e['frames_with_closed_curves']:6d} {e['frames_with_phantoms']:7d} {crossed(e):>9s} "
          f"{(ms if ms is not None else float('nan')):6.2f} {fps(r) if r != 'sam' else '-':>7s}")
for r in ["cold", "refined"]:
    line = open(f"{d}/{name}.{r}.log").read()
    cpu = re.findall(r"CPU ([0-9.]+) ms a frame", line)
    st = re.findall(r"stages ([0-9.]+) ms a frame \(median; mean distance ([0-9.]+), adapt ([0-9.]+), "
                    r"solve ([0-9.]+), renormalize ([0-9.]+), export ([0-9.]+)\)", line)
    if cpu and st:
        print(f"  daemon {r}: {fps(r)} frames/s, CPU {cpu[-1]} ms a frame; stages {st[-1][0]} ms "
              f"(distance {st[-1][1]}, adapt {st[-1][2]}, solve {st[-1][3]}, "
              f"renormalize {st[-1][4]}, export {st[-1][5]})")
PY
done
