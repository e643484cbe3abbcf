#!/usr/bin/env bash
# The moving-sensor replay of docs/benchmarks.md: 300 scans of the room and of the
# corridor by the Hokuyo UTM-30LX-like sensor (1,080 beams, 40 Hz) driving 0.1 m and
# turning up to 0.1 rad a frame, range noise 1 cm, 1% spurious short returns, 2% dropout.
# Each stream goes through the daemon warm with the frames' poses, warm without them,
# cold, and refined over a window of 10 frames (accumulate = 10), as fast as it takes
# them; the first also at the recorded 40 Hz. Prints the daemon's summaries, the peak
# memory, and per frame the accuracy of each against the scene.
# Usage: scripts/moving-replay.sh [FRAMES]   (default 300)
set -euo pipefail
. "$(dirname "$0")/lib.sh"
dir=target/moving-replay
n=${1:-300}
[ "$quick" = 1 ] && n=8
mkdir -p "$dir"
for scene in room corridor; do
  $bin synth "$scene" --sensor hokuyo-utm30lx --noise 0.01 --outliers 0.01 --dropout 0.02 \
    --frames "$n" --motion 0.1 --seed 3 -o "$dir/$scene.ndjson" --truth "$dir/$scene.truth.json"
  python3 - "$dir/$scene.ndjson" "$dir/$scene-nopose.ndjson" <<'PY'
import json, sys
with open(sys.argv[2], "w") as out:
    for line in open(sys.argv[1]):
        v = json.loads(line)
        v.pop("pose", None)
        out.write(json.dumps(v) + "\n")
PY
  echo "== $scene, $n frames"
  for run in warm:fast nopose:fast cold:fast refined:fast warm:recorded; do
    kind=${run%%:*}
    replay=${run##*:}
    input=$scene.ndjson
    [ "$kind" = nopose ] && input=$scene-nopose.ndjson
    warm=true
    [ "$kind" = cold ] && warm=false
    accumulate=0
    [ "$kind" = refined ] && accumulate=10
    cat > "$dir/$scene-$kind-$replay.toml" <<TOML
[input]
path = "$input"
replay = "$replay"
[output]
path = "$scene-$kind-$replay.out.ndjson"
[pipeline]
warm_start = $warm
accumulate = $accumulate
TOML
    echo "$kind, replay = $replay:"
    /usr/bin/time -f "  peak memory %M kB" $bin run -c "$dir/$scene-$kind-$replay.toml" 2>&1 |
      grep -E "isoline run:|peak memory"
  done
  for kind in warm cold refined; do
    $bin eval "$dir/$scene-$kind-fast.out.ndjson" --truth "$dir/$scene.truth.json" \
      --frames "$dir/$scene.ndjson" > "$dir/$scene-$kind.eval.json"
  done
  python3 - "$dir" "$scene" <<'PY'
import json, sys
d, s = sys.argv[1:]
kinds = ("warm", "cold", "refined")
recs = {k: [json.loads(l) for l in open(f"{d}/{s}-{k}-fast.out.ndjson")] for k in kinds}
ev = {k: json.load(open(f"{d}/{s}-{k}.eval.json"))["frames"] for k in kinds}
for k in kinds:
    h = sorted(f["hausdorff"] for f in ev[k])
    m = sorted(f["mean_distance"] for f in ev[k])
    x = sorted(r["stats"]["explained"] for r in recs[k])
    p = sorted(r["stats"]["fit_p90"] for r in recs[k])
    print(f"  {k}: Hausdorff median {h[len(h) // 2]:.3f} worst {h[-1]:.3f} m; "
          f"mean distance median {1e3 * m[len(m) // 2]:.2f} mm; "
          f"explained median {x[len(x) // 2]:.3f} min {x[0]:.3f}; "
          f"fit p90 median {1e3 * p[len(p) // 2]:.1f} mm")
ratio = max(w["stats"]["fit_p90"] / c["stats"]["fit_p90"] for w, c in zip(recs["warm"], recs["cold"]))
empty = sum(1 for w, c in zip(recs["warm"], recs["cold"]) if not w["polylines"] and c["polylines"])
print(f"  warm against cold, per frame: fit p90 at most {ratio:.2f} times; "
      f"{empty} frames without a curve where cold has one")
PY
done
