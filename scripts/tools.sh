#!/usr/bin/env bash
# The tools some benchmark scripts need, each made when missing, in .tools/ of the
# folder it is run from (sourced by scripts/lib.sh). Run on its own, it makes them
# all, for the measurements run by hand (scripts/cgal-peer.sh, glyphs.sh, map-logs.sh);
# the test suite needs none of them.
#
#   scripts/tools.sh        # CGAL's driver, the glyphs' Python and fonts, KISS-ICP

# CGAL's optimal-transport reconstruction as $otr, the driver scripts/cgal/otr2.cpp built
# into .tools/ (Debian's libcgal-dev installed first when missing, with apt-get, as root
# or through sudo): `$otr POINTS.xy TOLERANCE > EDGES` prints its edges.
need_otr2() {
  mkdir -p .tools
  if ! dpkg -s libcgal-dev >/dev/null 2>&1; then
    local sudo=""; [ "$(id -u)" = 0 ] || sudo=sudo
    $sudo apt-get install -y --no-install-recommends libcgal-dev libgmp-dev libmpfr-dev g++ >&2
  fi
  otr=.tools/otr2
  if [ ! -x "$otr" ] || [ scripts/cgal/otr2.cpp -nt "$otr" ]; then
    g++ -O2 -std=c++17 -o "$otr" scripts/cgal/otr2.cpp -lgmp -lmpfr
  fi
}

# A Python with numpy and scipy (and fontTools, for the glyphs) as $py: the virtual
# environment .tools/glyphs, made when missing.
need_numpy() {
  py=.tools/glyphs/bin/python
  if ! "$py" -c "import fontTools, numpy, scipy" 2> /dev/null; then
    rm -rf .tools/glyphs
    python3 -m venv .tools/glyphs
    .tools/glyphs/bin/pip install --quiet --disable-pip-version-check fonttools numpy scipy
  fi
}

# KISS-ICP (the `kiss-icp` package, a LiDAR odometry) as $kiss: the Python of the
# virtual environment .tools/kiss, made when missing.
need_kiss() {
  kiss=.tools/kiss/bin/python
  if ! "$kiss" -c "import kiss_icp" 2> /dev/null; then
    rm -rf .tools/kiss
    python3 -m venv .tools/kiss
    .tools/kiss/bin/pip install --quiet --disable-pip-version-check kiss-icp
  fi
}

# The fonts the glyph corpus draws from: Debian's fonts-dejavu-core, fonts-dejavu-extra
# (the condensed and extra-light faces), fonts-liberation and hershey-fonts-data
# (apt-get, as root or through sudo, when missing). Each package is checked, not only
# a folder: a machine with the DejaVu core alone made a corpus of other shapes.
need_fonts() {
  local pkgs=(fonts-dejavu-core fonts-dejavu-extra fonts-liberation hershey-fonts-data) missing=()
  for p in "${pkgs[@]}"; do
    dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
  done
  if [ "${#missing[@]}" -gt 0 ]; then
    local sudo=""; [ "$(id -u)" = 0 ] || sudo=sudo
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${missing[@]}" > /dev/null
  fi
}

if [ "${BASH_SOURCE[0]}" = "$0" ]; then
  set -euo pipefail
  cd "$(dirname "$0")/.."
  need_fonts
  need_otr2
  need_numpy
  need_kiss
fi
