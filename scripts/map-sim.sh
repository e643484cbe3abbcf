#!/usr/bin/env bash
# The simulated maps of docs/benchmarks.md, with truth: drives of 2,000 poses through
# the room, the corridor and the clutter scene, a person walking across each at 1 m/s,
# 1 cm range noise (1,080-beam Hokuyo UTM-30LX); then 20,000 scans round the loop
# scene (a 926 m corridor with rooms: 2 km, past every stretch twice) for memory and
# time per scan over a long run. Each map is scored by `isoline eval --map` against
# its scene; the tables come from the summaries (target/map-sim/).
# Usage: scripts/map-sim.sh      (QUICK=1: 20 scans of the room, 60 of the loop)
set -euo pipefail
. "$(dirname "$0")/lib.sh"
dir=target/map-sim
mkdir -p "$dir"
poses=2000; long=20000; scenes="room corridor clutter loop"
[ "$quick" = 1 ] && { poses=20; long=60; scenes="room loop"; }
runs=()
for scene in $scenes; do
  n=$poses; motion=0.05
  [ "$scene" = loop ] && { n=$long; motion=0.1; }
  frames=$dir/$scene.ndjson
  "$bin" synth "$scene" --frames "$n" --motion "$motion" --walker 1.0 --noise 0.01 \
    --seed 1 -o "$frames"
  # The scene and sensor for the scores (every frame's truth is not needed).
  "$bin" synth "$scene" --frames 1 --noise 0.01 -o "$dir/$scene-1.ndjson" \
    --truth "$dir/$scene-truth.json"
  tags=("$scene")
  # The long drive again with memory for 200 tiles (72 MB), fewer than it sees: tiles
  # leave for the disk and come back on the second lap.
  [ "$scene" = loop ] && [ "$quick" = 0 ] && {
    printf '[map]\nmax_tiles = 200\n' > "$dir/spill.toml"; tags+=(loop-spill); }
  for tag in "${tags[@]}"; do
    args=()
    [ "$tag" = loop-spill ] && args=(-c "$dir/spill.toml")
    "$bin" map "$frames" "${args[@]}" -q -o "$dir/$tag.svg" -o "$dir/$tag.geojson" \
      --stats "$dir/$tag.json"
    "$bin" eval "$dir/$tag.geojson" --map --frames "$frames" \
      --truth "$dir/$scene-truth.json" > "$dir/$tag-eval.json"
    runs+=("$dir/$tag")
  done
  rm -f "$frames"
done
python3 - "${runs[@]}" <<'PY'
import json, os, sys
print("| scene | scans | map within 3σ + 2 cells of the walls | largest distance to a wall | walls seen covered | static returns within 5 cm | map seen through | map length, pieces | CPU ms a scan: reconstruct / fuse | peak memory | tiles (bound) |")
print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
for run in sys.argv[1:]:
    s = json.load(open(run + ".json")); e = json.load(open(run + "-eval.json"))
    t = e["truth"]; c = s["scores"]; ms = s["cpu_ms_per_scan_by_phase"]; tl = s["tiles"]
    print(f"| {os.path.basename(run)} | {s['scans']} | {100*t['within_bound']:.1f}% | {100*t['to_walls_max']:.1f} cm "
          f"| {100*t['walls_seen_covered']:.1f}% | {100*c['static_within']:.1f}% | {100*c['seen_through']:.2f}% "
          f"| {c['length']:.0f} m, {c['pieces']} | {ms['reconstruct']:.2f} / {ms['fuse']:.2f} "
          f"| {s['peak_memory_bytes']/1e6:.0f} MB | {tl['resident']+tl['stored']} ({tl['bytes_bound']/1e6:.0f} MB) |")
for run in sys.argv[-2:]:
  s = json.load(open(run + ".json"))
  print()
  print(f"{os.path.basename(run)}, tile bound {s['tiles']['bytes_bound']/1e6:.0f} MB, {s['tiles']['spills']} spills:")
  print()
  print("| scans | ms a scan: reconstruct / fuse | tiles in memory, stored | resident memory |")
  print("|---:|---:|---:|---:|")
  done = 0
  for b in s["blocks"]:
    done += b["scans"]
    rss = b["resident_bytes"]
    print(f"| {done} | {b['reconstruct_ms']:.2f} / {b['fuse_ms']:.2f} | {b['tiles_resident']}, {b['tiles_stored']} "
          f"| {rss/1e6:.0f} MB |" if rss else f"| {done} | {b['reconstruct_ms']:.2f} / {b['fuse_ms']:.2f} | {b['tiles_resident']}, {b['tiles_stored']} | - |")
PY
