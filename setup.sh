#!/usr/bin/env bash
# Idempotent set-up on a fresh Debian machine (root, Python 3.11, no GPU, package registries only):
#   1. system packages: headless OpenGL through EGL (Mesa llvmpipe), libusb, and chromium (the report
#      page's browser test) -- skipped when present
#   2. a virtual environment .venv with this package, its test and bench extras -- skipped when up to date
#   3. numba kernels compiled once (python -m methods.warmup)                 -- cached, seconds when done
#   4. the named scenes and the LPIPS-VGG weights (`harness fetch`)         -- verified, no-op when present
#      (grape-small and playbot come from a mirror folder or GitHub; without either they are skipped)
# A second call reuses everything and takes a few seconds.
set -euo pipefail
cd "$(dirname "$0")"

PY=${PYTHON:-python3.11}
command -v "$PY" >/dev/null 2>&1 || PY=python3

# EGL + Mesa (llvmpipe) for the GL renderer; libusb because open3d's wheel links against it.
sys_ok() {
  ldconfig -p 2>/dev/null | grep -q 'libEGL_mesa.so' && ldconfig -p | grep -q 'libusb-1.0.so.0' &&
    ls /usr/lib/*/dri/swrast_dri.so >/dev/null 2>&1
}
if ! sys_ok; then
  echo "setup: installing EGL/Mesa and libusb system packages"
  SUDO=""; [ "$(id -u)" = 0 ] || SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq libegl1 libegl-mesa0 libgl1-mesa-dri libusb-1.0-0 >/dev/null
fi

# Debian's chromium: tests/test_report_page.py opens report.html in it (headless); skipped there when absent
if ! command -v chromium >/dev/null 2>&1; then
  echo "setup: installing chromium (headless browser for the report page's test)"
  SUDO=""; [ "$(id -u)" = 0 ] || SUDO="sudo"
  { $SUDO apt-get update -qq &&
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq chromium >/dev/null; } ||
    echo "setup: chromium could not be installed; the report page's browser test will be skipped"
fi

# pip, quiet: its errors and warnings are printed, but not the two notices every install of this
# package gives (setuptools' "Editable installation" note, an index location configured on the
# machine that does not exist); a failure prints everything pip said
pip_quiet() {
  local log status=0
  log=$(mktemp)
  PYTHONWARNINGS="ignore:Editable installation" .venv/bin/python -m pip -q "$@" >"$log" 2>&1 || status=$?
  if [ "$status" -ne 0 ]; then
    cat "$log" >&2
  else
    grep -v -E "^WARNING: Location '[^']*' is ignored: it is neither a file nor a directory\.$" "$log" >&2 || true
  fi
  rm -f "$log"
  return "$status"
}

stamp=.venv/.installed-$(sha256sum pyproject.toml | cut -c1-16)
if [ ! -f "$stamp" ]; then
  echo "setup: creating .venv and installing the package (torch comes from the machine's wheel store)"
  [ -x .venv/bin/python ] || "$PY" -m venv .venv
  pip_quiet install --upgrade pip
  pip_quiet install -e ".[test,bench,ray]"
  rm -f .venv/.installed-*
  touch "$stamp"
fi

# compile the numba kernels now (cached beside the sources), not in the user's first `harness prune`
.venv/bin/python -m methods.warmup
.venv/bin/harness fetch bonsai-7k bonsai-7k-mini luigi --weights
.venv/bin/harness fetch grape-small playbot ||
  echo "setup: grape-small/playbot are not available here (no mirror folder, no access to GitHub); runs skip them"
