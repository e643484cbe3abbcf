#!/usr/bin/env bash
# The density table of docs/benchmarks.md: the circle of radius 0.4 with Gaussian noise
# σ = 0.005 sampled by 10k, 100k and 1M points, reconstructed with the default
# parameters; prints a Markdown row per size with the noise estimate (hmin), the
# accuracy against the truth, the mesh, and the wall time and peak memory of the
# reconstruct process.
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
