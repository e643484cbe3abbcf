#!/usr/bin/env bash
# Simulated sweeps (docs/benchmarks.md, "The sweep's timing"): an RPLIDAR A1 (360
# degrees in the 100 ms between frames) and a Hokuyo URG-04LX (240 degrees in 67 ms)
# driving through the clutter scene, a scan every 5 cm at 10 Hz, each beam cast from
# where the sensor is when it is taken (`isoline synth --sweep`). The daemon with
# `register = true` on each stream with its true poses as input and without any pose,
# its frames with their beams' timing and with it removed (read as taken at once); its
# registered poses scored against the truth by `isoline eval --reference`.
# Usage: scripts/sweep-sim.sh     (QUICK=1: 60 scans)
set -euo pipefail
. "$(dirname "$0")/lib.sh"
dir=target/sweep-sim
mkdir -p "$dir"
frames=400
[ "$quick" = 1 ] && frames=60
echo "| sensor | input poses | beams | ATE m | RPE 1 m: m, deg | CPU ms a frame |"
echo "|---|---|---|---:|---:|---:|"
for sensor in rplidar-a1 hokuyo-urg04lx; do
  "$bin" synth clutter --sensor "$sensor" --frames "$frames" --motion 0.05 --seed 2 --sweep \
    -o "$dir/$sensor.ndjson"
  python3 - "$dir/$sensor" <<'PY'
import json, math, sys
stem = sys.argv[1]
with open(f"{stem}.ndjson") as f:
    frames = [json.loads(l) for l in f]
with open(f"{stem}.truth.tum", "w") as o:
    for d in frames:
        x, y, h = d["pose"]
        o.write(f"{d['t']} {x} {y} 0 0 0 {math.sin(h / 2)} {math.cos(h / 2)}\n")
for poses in ("given", "none"):
    for timing in ("timed", "untimed"):
        with open(f"{stem}-{poses}-{timing}.ndjson", "w") as o:
            for d in frames:
                d = dict(d)
                if poses == "none":
                    d.pop("pose")
                if timing == "untimed":
                    d.pop("time_increment")
                o.write(json.dumps(d) + "\n")
PY
  for poses in given none; do
    for timing in timed untimed; do
      stem=$dir/$sensor-$poses-$timing
      printf '[input]\npath = "%s"\nreplay = "fast"\n[output]\npath = "%s"\n[pipeline]\nregister = true\n' \
        "$(realpath "$stem.ndjson")" "$(realpath -m "$stem.out.ndjson")" > "$stem.toml"
      rm -f "$stem.out.ndjson"
      cpu=$("$bin" run -c "$stem.toml" 2>&1 | sed -n 's/.*CPU \([0-9.]*\) ms a frame.*/\1/p')
      python3 - "$stem" <<'PY'
import json, math, sys
stem = sys.argv[1]
with open(f"{stem}.out.ndjson") as f, open(f"{stem}.tum", "w") as o:
    for l in f:
        d = json.loads(l)
        x, y, h = d["registered_pose"]
        o.write(f"{d['t']} {x} {y} 0 0 0 {math.sin(h / 2)} {math.cos(h / 2)}\n")
PY
      "$bin" eval "$stem.tum" --reference "$dir/$sensor.truth.tum" > "$stem.eval.json"
      python3 - "$sensor" "$poses" "$timing" "$stem.eval.json" "$cpu" <<'PY'
import json, sys
sensor, poses, timing, path, cpu = sys.argv[1:]
e = json.load(open(path))
r = e["rpe"][0]
beams = "timed" if timing == "timed" else "taken at once"
print(f"| {sensor} | {poses} | {beams} | {e['ate_m']:.4f} | {r['translation_m']:.4f}, {r['heading_deg']:.3f} | {cpu} |")
PY
    done
  done
done
