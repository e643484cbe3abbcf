#!/usr/bin/env bash
# The scan replay of docs/benchmarks.md: 400 frames of a Hokuyo UTM-30LX-like sensor
# (1,080 beams, 40 Hz) in the simulated room, range noise 1 cm, 2% dropout, once from a
# static sensor and once driving round the room at 1 m/s (0.025 m a frame). Each stream
# goes through the daemon as fast as it takes it and at the recorded 40 Hz; prints the
# daemon's summary, the scan scores of `isoline eval`, how much hmin varies from frame
# to frame, and the same scores for the split-and-merge baseline
# (scripts/split_and_merge.py) on the same frames.
# Usage: scripts/scan-replay.sh [FRAMES]   (default 400)
set -euo pipefail
. "$(dirname "$0")/lib.sh"
dir=target/scan-replay
n=${1:-400}
[ "$quick" = 1 ] && n=8
mkdir -p "$dir"
score() { # records truth frames label
  $bin eval "$1" --truth "$2" --frames "$3" > "$1.eval.json"
  python3 - "$1.eval.json" "$4" <<'PY'
import json, sys
v = json.load(open(sys.argv[1]))
fs = v["frames"]
h = sorted(f["hausdorff"] for f in fs)
print(f"  {sys.argv[2]}: Hausdorff median {h[len(h) // 2]:.3f} worst {h[-1]:.3f} m; "
      f"returns explained mean {v['returns_explained_mean']:.3f} min {v['returns_explained_min']:.3f}; "
      f"curve in free space max {v['free_space_share_max']:.4f}; "
      f"openings bridged {v['openings_bridged']:.0f}, walls missed {v['walls_missed']:.0f} "
      f"over {len(fs)} frames")
PY
}
for motion in 0 0.025; do
  name=room-$motion
  $bin synth room --sensor hokuyo-utm30lx --noise 0.01 --dropout 0.02 --frames "$n" \
    --motion "$motion" --seed 21 -o "$dir/$name.ndjson" --truth "$dir/$name.truth.json"
  echo "== room, motion $motion m a frame, $n frames"
  for replay in fast recorded; do
    cat > "$dir/$name-$replay.toml" <<TOML
[input]
path = "$name.ndjson"
replay = "$replay"
[output]
path = "$name-$replay.out.ndjson"
TOML
    echo "replay = $replay"
    $bin run -c "$dir/$name-$replay.toml"
  done
  score "$dir/$name-fast.out.ndjson" "$dir/$name.truth.json" "$dir/$name.ndjson" isoline
  python3 - "$dir/$name-fast.out.ndjson" <<'PY'
import json, statistics as st, sys
rs = [json.loads(l)["stats"] for l in open(sys.argv[1])]
h = [r["hmin"] for r in rs]
ms = sorted(r["ms"]["total"] for r in rs[1:])
print(f"  hmin: min {min(h):.4f} median {st.median(h):.4f} max {max(h):.4f} m, "
      f"relative standard deviation {st.pstdev(h) / st.mean(h):.1%}; "
      f"warm frames {sum(r['warm_start'] for r in rs)}/{len(rs)}, "
      f"compute per frame median {ms[len(ms) // 2]:.1f} ms")
PY
  python3 scripts/split_and_merge.py "$dir/$name.ndjson" "$dir/$name.sm.ndjson"
  score "$dir/$name.sm.ndjson" "$dir/$name.truth.json" "$dir/$name.ndjson" split-and-merge
done
