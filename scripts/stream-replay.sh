#!/usr/bin/env bash
# The daemon run of the README: a synthetic moving ellipse, 200 frames of 1,000 points,
# noise 0.003, 0.003 of rigid motion per frame, replayed as fast as the pipeline takes
# it, once with warm starts and twice without: from the default medial start, and from
# the tube start, whose capture phase warm starts were first measured against. Prints
# the daemon's summary lines (frames per second, latency p50/p99, median iterations)
# and the worst and median per-frame Hausdorff distance to the truth. Then the warm run
# again at the stream's recorded pace (20 frames per second, a live scanner's), whose
# latencies are those of a pipeline that keeps up rather than of a queue. HMIN=...
# overrides the mesh size (default 0.002).
set -euo pipefail
. "$(dirname "$0")/lib.sh"
dir=target/stream-200
hmin=${HMIN:-0.002}
mkdir -p "$dir"
frames=200; [ "$quick" = 1 ] && frames=10
$bin synth ellipse --points 1000 --noise 0.003 --frames $frames --motion 0.003 --seed 8 \
  --stream lidar0 -o "$dir/frames.ndjson" --truth "$dir/truth.json"
for run in warm cold cold-tube paced; do
  warm=true; replay=fast; init=medial
  [ "$run" = cold ] && warm=false
  [ "$run" = cold-tube ] && warm=false && init=tube
  [ "$run" = paced ] && replay=recorded
  cat > "$dir/$run.toml" <<TOML
[input]
path = "frames.ndjson"
replay = "$replay"
[output]
path = "out-$run.ndjson"
[pipeline]
warm_start = $warm
[mesh]
hmin = $hmin
[solver]
init = "$init"
TOML
  echo "warm_start = $warm, replay = $replay, hmin = $hmin, init = $init"
  $bin run -c "$dir/$run.toml"
  $bin eval "$dir/out-$run.ndjson" --truth "$dir/truth.json" | python3 -c '
import json, sys
v = json.load(sys.stdin)
h = sorted(f["hausdorff"] for f in v["frames"])
c = sum(f["components_recon"] == f["components_truth"] for f in v["frames"])
print(f"  Hausdorff median {h[len(h)//2]:.2e} worst {h[-1]:.2e}; right components in {c}/{len(h)} frames")'
done
