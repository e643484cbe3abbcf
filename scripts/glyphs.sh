#!/usr/bin/env bash
# The glyph corpus (scripts/glyphs.py): font outlines and Hershey strokes sampled at
# several densities and noise levels, with and without 5% outliers, reconstructed with
# the defaults and scored against their truth. Installs what it reads: Debian's
# fonts-dejavu-core and hershey-fonts-data (apt-get, when missing) and fontTools, numpy
# and scipy in a fresh virtual environment (.tools/glyphs).
#
#   scripts/glyphs.sh [dev|test] [CASES] [OUT_DIR]   # default: test 600 target/glyphs-PART
#
# Prints one JSON line a case, then the Markdown table of docs/benchmarks.md.
set -euo pipefail
. "$(dirname "$0")/lib.sh"
part=${1:-test}
cases=${2:-600}
[ "$quick" = 1 ] && cases=4
out=${3:-target/glyphs-$part}
if [ ! -d /usr/share/hershey-fonts ] || [ ! -d /usr/share/fonts/truetype/dejavu ]; then
  sudo=""
  [[ $(id -u) -ne 0 ]] && sudo="sudo"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq fonts-dejavu-core hershey-fonts-data > /dev/null
fi
py=.tools/glyphs/bin/python
if ! "$py" -c "import fontTools, numpy, scipy" 2> /dev/null; then
  rm -rf .tools/glyphs
  python3 -m venv .tools/glyphs
  .tools/glyphs/bin/pip install --quiet --disable-pip-version-check fonttools numpy scipy
fi
rm -rf "$out"
"$py" scripts/glyphs.py make "$out" --part "$part" --cases "$cases"
ls "$out"/*.case.json | sed 's/\.case\.json$//' \
  | xargs -P 2 -I{} sh -c '"$0" reconstruct {}.ndjson -o {}.recon.ndjson 2> {}.err || true' "$bin"
"$py" scripts/glyphs.py score "$out"
