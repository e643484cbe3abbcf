#!/usr/bin/env bash
# The simulated rows of docs/benchmarks.md's pose table: drives whose true poses are
# known, each with its poses replaced by drifting wheel odometry
# (scripts/drift-odometry.py, seeds $SEEDS, default "1 2 3"), mapped by
# `isoline map --register` and scored against the truth by `isoline eval --reference`.
# A SICK LMS1xx (541 beams over 270 degrees, 1.2 cm range noise) with a scan every
# 0.7 m, as the CARMEN logs are: 600 scans through the room, the corridor and the
# clutter scene, and 1,400 (980 m) round the loop scene's 926 m corridor, which closes
# its loop; then a Hokuyo URG-04LX (4 m reach) at 10 Hz, a scan every 5 cm, 1,500 scans
# through the clutter scene and the corridor. Rows: medians over the seeds.
# Usage: scripts/registration-sim.sh     (QUICK=1: 60 scans of the clutter scene, seed 1)
set -euo pipefail
. "$(dirname "$0")/lib.sh"
dir=target/registration-sim
mkdir -p "$dir"
seeds=${SEEDS:-1 2 3}
runs="sick-lms1xx:0.7:room:600 sick-lms1xx:0.7:corridor:600 sick-lms1xx:0.7:clutter:600
  sick-lms1xx:0.7:loop:1400 hokuyo-urg04lx:0.05:clutter:1500 hokuyo-urg04lx:0.05:corridor:1500"
[ "$quick" = 1 ] && { seeds=1; runs="sick-lms1xx:0.7:clutter:60"; }
: > "$dir/rows.tsv"
for run in $runs; do
  IFS=: read -r sensor step scene n <<< "$run"
  name=$scene-$sensor
  "$bin" synth "$scene" --sensor "$sensor" --frames "$n" --motion "$step" --seed 1 \
    -o "$dir/$name.ndjson"
  for seed in $seeds; do
    stem=$dir/$name-s$seed
    scripts/drift-odometry.py "$dir/$name.ndjson" "$stem.ndjson" "$stem.truth.tum" "$seed"
    for way in odometry register; do
      args=(); [ "$way" = register ] && args=(--register)
      "$bin" map "$stem.ndjson" "${args[@]}" -q -o "$stem-$way.svg" --stats "$stem-$way.json" \
        --trajectory "$stem-$way.tum" 2> /dev/null
      "$bin" eval "$stem-$way.tum" --reference "$stem.truth.tum" > "$stem-$way.eval.json"
      printf '%s\t%s, %s cm\t%s\t%s\t%s\t-\n' "$scene" "$sensor" "$(python3 -c "print(round($step * 100))")" \
        "$way" "$stem-$way.eval.json" "$stem-$way.json" >> "$dir/rows.tsv"
    done
  done
done
echo "| scene | sensor, a scan every | poses | runs | ATE m | RPE 1 m: m, deg | RPE 10 m: m, deg | static returns within 5 cm | seen through | loops | CPU ms a scan (registration / all) |"
echo "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|"
python3 scripts/pose-rows.py "$dir/rows.tsv"
