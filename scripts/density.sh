#!/usr/bin/env bash
# The density table of docs/benchmarks.md: the circle of radius 0.4 with Gaussian noise
# σ = 0.005 sampled by 10k, 100k and 1M points, reconstructed with the default
# parameters; prints a Markdown row per size with the noise estimate (hmin), the
# accuracy against the truth, the mesh, and the wall time and peak memory of the
# reconstruct process; then the same for two bands wider than the windows.
set -euo pipefail
. "$(dirname "$0")/lib.sh"
dir=target/density
mkdir -p "$dir"
sizes="10000 100000 1000000"; [ "$quick" = 1 ] && sizes="10000"
echo "| points | hmin (noise estimate) | Hausdorff | mean distance | loops | vertices | seconds | peak MiB |"
echo "|---:|---:|---:|---:|---:|---:|---:|---:|"
for n in $sizes; do
  f="$dir/circle-$n"
  $bin synth circle --points "$n" --noise 0.005 --seed 1 -o "$f.ndjson" --truth "$f.truth.json"
  python3 - "$bin" "$f" "$n" <<'PY'
import json, resource, subprocess, sys, time
bin_, f, n = sys.argv[1:]
# A point file, one `x y` a line: a million points on one NDJSON line pass the 16 MiB
# bound the NDJSON reader holds every line to.
with open(f + ".ndjson") as src, open(f + ".xy", "w") as xy:
    xy.writelines(f"{x!r} {y!r}\n" for x, y in json.loads(src.readline())["points"])
t0 = time.monotonic()
subprocess.run([bin_, "reconstruct", f + ".xy", "-o", f + ".recon.ndjson",
                "--stats", f + ".stats.json"], check=True)
seconds = time.monotonic() - t0
peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
e = json.loads(subprocess.run([bin_, "eval", f + ".recon.ndjson", "--truth", f + ".truth.json"],
                              check=True, capture_output=True).stdout)
s = json.load(open(f + ".stats.json"))
print(f"| {int(n):,} | {s['hmin']:.2e} | {e['hausdorff']:.2e} | {e['mean_distance']:.2e} | "
      f"{e['components_recon']} | {s['vertices']} | {seconds:.2f} | {peak:.0f} |")
PY
done
# Bands wider than the noise measurement's windows, drawn by the graph over the samples
# (docs/method.md, "Noise bands wider than the windows"): the simulator's strokes and a
# ring, densely sampled; wall time, the graph's share of it (the export stage), and
# what came out.
echo
echo "| shape | points | σ | curves | warning | export ms | seconds |"
echo "|---|---:|---:|---:|---|---:|---:|"
wide="strokes:100000:0.02 circle:200000:0.03"; [ "$quick" = 1 ] && wide="strokes:20000:0.02"
for spec in $wide; do
  IFS=: read -r shape n sigma <<< "$spec"
  f="$dir/$shape-$n-$sigma"
  $bin synth "$shape" --points "$n" --noise "$sigma" --seed 1 -o "$f.ndjson" --truth "$f.truth.json"
  start=$(date +%s.%N)
  $bin reconstruct "$f.ndjson" -o "$f.recon.ndjson"
  end=$(date +%s.%N)
  python3 - "$f" "$shape" "$n" "$sigma" "$start" "$end" <<'PY'
import json, sys
f, shape, n, sigma, start, end = sys.argv[1:]
r = json.loads(open(f + ".recon.ndjson").readline())
w = "; ".join(r.get("warnings", [])).split(":")[0] or "-"
print(f"| {shape} | {int(n):,} | {sigma} | {len(r['polylines'])} | {w} | {r['stats']['ms']['export']:.0f} | "
      f"{float(end) - float(start):.2f} |")
PY
done
