#!/usr/bin/env bash
# The maps of docs/benchmarks.md: each CARMEN log (*.log.gz, as published) and NDJSON
# beam stream (*.ndjson.gz) in $ISOLINE_REAL fused by `isoline map` into one
# world-frame map (target/map-logs/NAME.svg, .geojson and the run's summary .json), the
# beam streams (odometry poses) also with each scan aligned onto the map, to show what
# drift does and what the alignment does about it;
# then one table row a run from the summaries, and how the returns spread about each
# map by range (scripts/map-spread.py, numpy and scipy in .tools/glyphs).
# Usage: ISOLINE_REAL=DIR scripts/map-logs.sh
set -euo pipefail
. "$(dirname "$0")/lib.sh"
need_recordings
dir=target/map-logs
mkdir -p "$dir"
printf '[map]\nalign = true\n' > "$dir/align.toml"
runs=()
for gz in "$real"/*.gz; do
  name=$(basename "$gz" .gz)
  case $name in
    *.log) name=${name%.log}; input=$gz; configs=("") ;;
    *.ndjson) name=${name%.ndjson}; input=$gz; configs=("" "$dir/align.toml") ;;
    *) continue ;;
  esac
  for cfg in "${configs[@]}"; do
    tag=$name; args=()
    [ -n "$cfg" ] && { tag=$name-align; args=(-c "$cfg"); }
    "$bin" map "$input" "${args[@]}" -q -o "$dir/$tag.svg" -o "$dir/$tag.geojson" \
      --stats "$dir/$tag.json"
    runs+=("$dir/$tag.json")
  done
done
python3 - "${runs[@]}" <<'PY'
import json, os, sys
print("| recording | scans | static returns within 5 cm | map seen through | map length, pieces | scans' curves: length, seen through | CPU ms a scan: reconstruct / fuse (all) | peak memory | tiles (bound) |")
print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
for path in sys.argv[1:]:
    s = json.load(open(path)); c = s["scores"]; t = s["tiles"]; ms = s["cpu_ms_per_scan_by_phase"]
    name = os.path.basename(path)[:-5]
    print(f"| {name} | {s['scans']} | {100*c['static_within']:.1f}% | {100*c['seen_through']:.2f}% "
          f"| {c['length']:.0f} m, {c['pieces']} | {c['union_length']:.0f} m, {100*c['union_seen_through']:.0f}% "
          f"| {ms['reconstruct']:.2f} / {ms['fuse']:.2f} ({s['cpu_ms_per_scan']:.1f}) "
          f"| {s['peak_memory_bytes']/1e6:.0f} MB | {t['resident']+t['stored']} ({t['bytes_bound']/1e6:.0f} MB) |")
PY
# How each map's returns spread about it by range, and what one curve per half metre of
# wall could hold at best (scripts/map-spread.py).
need_numpy
for gz in "$real"/*.gz; do
  name=$(basename "$gz" .gz); name=${name%.log}; name=${name%.ndjson}
  echo "$name:"
  "$py" scripts/map-spread.py "$gz" "$dir/$name.geojson"
done
