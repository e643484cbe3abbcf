#!/usr/bin/env bash
# Refinement over frames on a static scanner, seed by seed: the simulated room, 20 frames
# at 1 cm range noise without motion, through the daemon single-frame (warm starts) and
# refined over 10 frames (accumulate = 10), each scored against the room's walls by
# `isoline eval --truth`. Prints per seed the median over frames 10-20 of the refined
# frame's mean distance and Hausdorff distance to the walls, as ratios to a single
# frame's. Seeds 1, 3, 5 and 7 were looked at while the refinement's rules were chosen;
# the others were held out.
# Usage: scripts/static-refinement.sh [SEED...]   (default 1 to 16)
set -euo pipefail
. "$(dirname "$0")/lib.sh"
dir=target/static-refinement
seeds=("$@")
[ ${#seeds[@]} = 0 ] && seeds=($(seq 1 16))
frames=20
[ "$quick" = 1 ] && { seeds=(1); frames=11; }
for seed in "${seeds[@]}"; do
  d=$dir/$seed
  rm -rf "$d"
  mkdir -p "$d"
  $bin synth room --noise 0.01 --frames "$frames" --motion 0 --seed "$seed" \
    -o "$d/frames.ndjson" --truth "$d/truth.json" 2>/dev/null
  for run in single:"warm_start = true" refined:"accumulate = 10"; do
    name=${run%%:*}
    # Paths in a configuration are relative to its file.
    printf '[input]\npath = "%s"\nreplay = "fast"\n[output]\npath = "%s"\n[pipeline]\n%s\n' \
      frames.ndjson "$name.ndjson" "${run#*:}" > "$d/$name.toml"
    $bin run -c "$d/$name.toml" 2>/dev/null
    $bin eval "$d/$name.ndjson" --truth "$d/truth.json" --frames "$d/frames.ndjson" > "$d/$name.eval.json"
  done
  python3 - "$d" "$seed" <<'PY'
import json, statistics, sys
d, seed = sys.argv[1], sys.argv[2]
def median(run, key):
    frames = json.load(open(f"{d}/{run}.eval.json"))["frames"][9:]
    return statistics.median(f[key] for f in frames)
ms, mr = median("single", "mean_distance"), median("refined", "mean_distance")
hs, hr = median("single", "hausdorff"), median("refined", "hausdorff")
held = "dev" if seed in ("1", "3", "5", "7") else "held out"
print(f"seed {seed} ({held}): mean distance {mr / ms:.3f} ({1000 * ms:.2f} -> {1000 * mr:.2f} mm), "
      f"Hausdorff {hr / hs:.3f} ({1000 * hs:.1f} -> {1000 * hr:.1f} mm)")
PY
done
