#!/usr/bin/env bash
# The Python package's build and tests: a wheel built from this checkout (maturin,
# crates/py) is installed into a fresh virtual environment (.tools/py) with numpy, pytest
# (with xdist: two workers) and matplotlib, then python/tests runs against target/debug/isoline (built
# when missing). scripts/test.sh runs it after the Rust tests.
#
#   scripts/python.sh                    # all of it
#   scripts/python.sh setup              # only the fresh environment (no Rust build)
#   scripts/python.sh test               # the wheel and the tests, in that environment
#   ISOLINE_REAL=DIR scripts/python.sh   # also the tests on the real recordings in DIR
#
# The wheel is built with cargo's dev profile, whose isoline-core is optimised
# (Cargo.toml), so that it reuses the test build's compiled crates (crates/py/Cargo.toml
# says how); `pip install .` builds the optimised release wheel users get.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"
venv=.tools/py
phase=${1:-all}

setup() {
  rm -rf "$venv"
  python3 -m venv "$venv"
  "$venv/bin/pip" install --quiet --disable-pip-version-check "maturin>=1.9,<2" numpy pytest pytest-xdist matplotlib
}

test() {
  rm -rf target/wheels
  "$venv/bin/maturin" build --quiet --profile dev --interpreter "$venv/bin/python" --out target/wheels
  # Forced: a wheel of the same version from an earlier run would otherwise stay.
  "$venv/bin/pip" install --quiet --disable-pip-version-check --force-reinstall --no-deps --no-index --find-links target/wheels isoline
  [[ -x target/debug/isoline ]] || cargo build --quiet --bin isoline
  # From outside the checkout, so that `import isoline` is the installed wheel.
  cd /tmp
  ISOLINE_BIN="$root/target/debug/isoline" "$root/$venv/bin/python" -m pytest -q -n 2 "$root/python/tests"
}

case $phase in
  setup) setup ;;
  test) test ;;
  all) setup; test ;;
  *) echo "usage: scripts/python.sh [setup|test]" >&2; exit 2 ;;
esac
