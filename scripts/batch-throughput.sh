#!/usr/bin/env bash
# Batch throughput of the README: 100 synthetic files of 5,000 points each (the synth
# shapes in turn, noise 0.002), processed by `isoline batch` with every core, then one by
# one (one `isoline reconstruct` after the other). Prints both wall times.
set -euo pipefail
. "$(dirname "$0")/lib.sh"
dir=target/batch-100
rm -rf "$dir"; mkdir -p "$dir/in"
shapes=(circle ellipse square star c two-circles annulus)
files=100; points=5000
[ "$quick" = 1 ] && files=4 && points=500
for i in $(seq 0 $((files - 1))); do
  s=${shapes[$((i % 7))]}
  $bin synth "$s" --points $points --noise 0.002 --seed "$i" -o "$dir/in/$(printf %03d $i)-$s.ndjson"
done
cat > "$dir/job.toml" <<'TOML'
[batch]
inputs = ["in/*.ndjson"]
output = "out"
formats = ["ndjson"]
TOML
start=$(date +%s%N)
$bin batch -c "$dir/job.toml" > "$dir/batch.txt"
batch=$(( $(date +%s%N) - start ))
start=$(date +%s%N)
for f in "$dir"/in/*.ndjson; do $bin reconstruct "$f" -o "$dir/one.ndjson"; done
serial=$(( $(date +%s%N) - start ))
tail -2 "$dir/batch.txt"
python3 -c "b, s = $batch / 1e9, $serial / 1e9; print(f'batch: {b:.1f} s ({$files / b:.2f} files/s); one by one: {s:.1f} s; speed-up {s / b:.2f}x')"
