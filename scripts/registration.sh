#!/usr/bin/env bash
# The pose table of docs/benchmarks.md: each CARMEN log (*.log.gz) and ROS 2 bag
# (*.mcap, poses from $ODOMETRY, default /odom) in $ISOLINE_REAL with its corrected
# poses replaced by drifting wheel odometry (scripts/drift-odometry.py, seeds $SEEDS,
# default "1 2 3"), mapped by `isoline map` five ways: the odometry alone, the odometry
# with [map] align, --register without loops, --register (loops closed), and the
# corrected poses themselves; each estimated trajectory scored against the corrected
# one by `isoline eval --reference` (ATE after the best rigid alignment, RPE over 1 m
# and 10 m); beam streams without a reference (*.ndjson.gz, real wheel odometry) are
# mapped with their own poses and with --register, read as taken at once and with their
# beams' timing ([scan] time_increment, $TIME_INCREMENT seconds, default 0.1 s / 1024:
# a Hokuyo URG-04LX). Rows: one a recording and way,
# medians over the seeds. Then the daemon with `register = true` on seed 1's odometry,
# single frames and refined over 10 (`accumulate = 10`), scored by `isoline eval
# --frames`: the next scan's returns that see what a frame saw, placed by the input
# poses and by the registered ones, their mean distance to the frame's curves.
# Usage: ISOLINE_REAL=DIR scripts/registration.sh
set -euo pipefail
. "$(dirname "$0")/lib.sh"
need_recordings
dir=target/registration
mkdir -p "$dir"
seeds=${SEEDS:-1 2 3}
[ "$quick" = 1 ] && seeds=1
printf '[map]\nalign = true\n' > "$dir/align.toml"
printf '[register]\nloops = false\n' > "$dir/noloops.toml"
printf '[scan]\ntime_increment = %s\n' "${TIME_INCREMENT:-9.765625e-5}" > "$dir/timed.toml"
: > "$dir/rows.tsv"
run() { # NAME WAY INPUT REF [ARGS...]
  local name=$1 way=$2 input=$3 ref=$4; shift 4
  "$bin" map "$input" "$@" -q -o "$dir/$name-$way.svg" --stats "$dir/$name-$way.json" \
    --trajectory "$dir/$name-$way.tum" 2> /dev/null
  if [ -n "$ref" ]; then
    "$bin" eval "$dir/$name-$way.tum" --reference "$ref" > "$dir/$name-$way.eval.json"
  else
    echo '{}' > "$dir/$name-$way.eval.json"
  fi
  printf '%s\t%s\t%s\t%s\t-\n' "${name%-s[0-9]*}" "$way" "$dir/$name-$way.eval.json" "$dir/$name-$way.json" >> "$dir/rows.tsv"
}
for input in "$real"/*.log.gz "$real"/*.mcap; do
  [ -e "$input" ] || continue
  base=$(basename "$input"); base=${base%.gz}; base=${base%.log}; base=${base%.mcap}
  args=(); case $input in *.mcap) args=(--odometry "${ODOMETRY:-/odom}") ;; esac
  "$bin" convert "$input" "${args[@]}" -o "$dir/$base.ndjson" 2> /dev/null
  for seed in $seeds; do
    name=$base-s$seed
    scripts/drift-odometry.py "$dir/$base.ndjson" "$dir/$name.ndjson" "$dir/$name.ref.tum" "$seed"
    run "$name" odometry "$dir/$name.ndjson" "$dir/$name.ref.tum"
    run "$name" align "$dir/$name.ndjson" "$dir/$name.ref.tum" -c "$dir/align.toml"
    run "$name" register-noloops "$dir/$name.ndjson" "$dir/$name.ref.tum" --register -c "$dir/noloops.toml"
    run "$name" register "$dir/$name.ndjson" "$dir/$name.ref.tum" --register
  done
  run "$base" corrected "$dir/$base.ndjson" "$dir/$base-s1.ref.tum"
  run "$base" corrected-register "$dir/$base.ndjson" "$dir/$base-s1.ref.tum" --register
done
for input in "$real"/*.ndjson.gz; do
  [ -e "$input" ] || continue
  base=$(basename "$input" .ndjson.gz)
  run "$base" odometry "$input" ""
  run "$base" register "$input" "" --register
  run "$base" odometry-timed "$input" "" -c "$dir/timed.toml"
  run "$base" register-timed "$input" "" --register -c "$dir/timed.toml"
done
echo "| recording | poses | runs | ATE m | RPE 1 m: m, deg | RPE 10 m: m, deg | static returns within 5 cm | seen through | loops | CPU ms a scan (registration / all) |"
echo "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|"
python3 scripts/pose-rows.py "$dir/rows.tsv"
echo
echo "| recording | frames | next scan by input poses, cm | by registered poses, cm | nearer | nearer than a registered single frame | CPU ms a frame |"
echo "|---|---|---:|---:|---:|---:|---:|"
for input in "$dir"/*-s1.ndjson; do
  [ -e "$input" ] || continue
  name=$(basename "$input" -s1.ndjson)
  for acc in 0 10; do
    out=$dir/$name-daemon-$acc.ndjson
    printf '[input]\npath = "%s"\nreplay = "fast"\n[output]\npath = "%s"\n[pipeline]\nregister = true\naccumulate = %s\n' \
      "$(realpath "$input")" "$(realpath -m "$out")" "$acc" > "$dir/daemon-$acc.toml"
    rm -f "$out"
    cpu=$("$bin" run -c "$dir/daemon-$acc.toml" 2>&1 | sed -n 's/.*CPU \([0-9.]*\) ms a frame.*/\1/p')
    "$bin" eval "$out" --frames "$input" > "$out.eval.json"
    python3 - "$name" "$acc" "$out.eval.json" "$cpu" "$dir/$name-daemon-0.ndjson.eval.json" <<'PY'
import json, sys
name, acc, path, cpu, single = sys.argv[1:]
e = json.load(open(path))
a, b = e["next_scan_by_input_pose"], e["next_scan_by_registered_pose"]
kind = "single" if acc == "0" else f"refined over {acc}"
# Refinement against the registered single frame of the same run.
s = json.load(open(single))["next_scan_by_registered_pose"]
gain = "" if acc == "0" else f"{100*(1-b/s):.1f}%"
print(f"| {name} | {kind} | {100*a:.2f} | {100*b:.3f} | {100*(1-b/a):.0f}% | {gain} | {cpu} |")
PY
  done
done

echo
# How far the references themselves are off (scripts/reference-noise.py): the
# reference's, the registered trajectory's (seed 1) and an independent pairwise ICP's
# motion between consecutive scans and over 10 m of path, split by the three-cornered
# hat.
need_numpy
echo "| recording | steps (median length) | reference's own error a step: along cm, sideways cm, deg | registered's | pairwise ICP's | over 10 m: reference's | registered's | ICP chain's |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|"
for input in "$dir"/*-s1.ndjson; do
  [ -e "$input" ] || continue
  name=$(basename "$input" -s1.ndjson)
  "$py" scripts/reference-noise.py "$dir/$name.ndjson" "$dir/$name-s1-register.tum" \
    | python3 -c "
import json, sys
e = json.load(sys.stdin); f = lambda v: ', '.join(f'{x:.2f}' for x in v)
s, t = e['step'], e.get('over_10_m', {})
g = lambda k: f(t[k]) if k in t else ''
print(f\"| $name | {s['pairs']} ({e['step_m']:.2f} m) | {f(s['reference'])} | {f(s['estimate'])} | {f(s['icp'])} | {g('reference')} | {g('estimate')} | {g('icp')} |\")"
done
