#!/usr/bin/env bash
# The glyph corpus (scripts/glyphs.py): font outlines, Hershey strokes and procedural
# shapes (spirals, spiral bands, combs with narrow slots, rings with narrow gaps)
# sampled at several densities, noise levels up to 1% of their size and samplings
# (uniform, or a density varying 5-fold along the curves), with and without 5%
# outliers, reconstructed with the defaults and scored against their truth. Installs what it
# reads: Debian's fonts-dejavu-core, fonts-dejavu-extra, fonts-liberation and
# hershey-fonts-data (apt-get, when missing) and fontTools, numpy and scipy in a fresh
# virtual environment (.tools/glyphs).
#
#   scripts/glyphs.sh [dev|test] [CASES] [OUT_DIR]   # default: test 600 target/glyphs-PART
#   CGAL=N scripts/glyphs.sh ...                     # also CGAL on the first N cases
#   GRID=1 scripts/glyphs.sh test 100 ...            # 100 distinct shapes (the part's
#                                                    # procedural ones first), each at every
#                                                    # noise level and sampling, with and
#                                                    # without outliers
#
# Prints one JSON line a case, then the Markdown tables of docs/benchmarks.md (the last
# one the point-cloud contract's measures: empty results, stars, loops, strokes missed); with CGAL,
# then the same for CGAL's optimal-transport reconstruction (scripts/cgal/otr2.cpp,
# Wasserstein tolerance 0.01, built as scripts/cgal-peer.sh builds it) and for isoline
# on the same cases.
set -euo pipefail
. "$(dirname "$0")/lib.sh"
part=${1:-test}
cases=${2:-600}
[ "$quick" = 1 ] && cases=4
out=${3:-target/glyphs-$part}
need_fonts
need_numpy
rm -rf "$out"
grid=()
[ "${GRID:-0}" = 1 ] && grid=(--grid)
"$py" scripts/glyphs.py make "$out" --part "$part" --cases "$cases" "${grid[@]}"
ls "$out"/*.case.json | sed 's/\.case\.json$//' \
  | xargs -P 2 -I{} sh -c '"$0" reconstruct {}.ndjson -o {}.recon.ndjson 2> {}.err || true' "$bin"
"$py" scripts/glyphs.py score "$out"
cgal=${CGAL:-0}
[ "$quick" = 1 ] && [ "$cgal" -gt 0 ] && cgal=1
if [ "$cgal" -gt 0 ]; then
  need_otr2
  mkdir -p "$out/cgal"
  for c in $(ls "$out"/*.case.json | sed 's/\.case\.json$//' | head -n "$cgal"); do
    name=$(basename "$c")
    cp "$c".case.json "$c".truth.json "$c".ndjson "$c".recon.ndjson "$out/cgal/"
    python3 scripts/cgal/score.py xy "$c.ndjson" "$out/cgal/$name.xy"
    "$otr" "$out/cgal/$name.xy" 0.01 > "$out/cgal/$name.edges" 2> "$out/cgal/$name.cgal-ms" || true
  done
  "$py" scripts/glyphs.py edges "$out/cgal"
  echo "CGAL:"
  "$py" scripts/glyphs.py score "$out/cgal" --peer cgal | grep '^|'
  echo "isoline, the same cases:"
  "$py" scripts/glyphs.py score "$out/cgal" | grep '^|'
fi
