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

stamp=.venv/.installed-$(sha256sum pyproject.toml | cut -c1-16)
if [ ! -f "$stamp" ]; then
  echo "setup: creating .venv and installing the package (torch comes from the machine's wheel store)"
  [ -x .venv/bin/python ] || "$PY" -m venv .venv
  .venv/bin/python -m pip install -q --upgrade pip
  .venv/bin/python -m pip install -q -e ".[test,bench,ray]"
  rm -f .venv/.installed-*
  touch "$stamp"
fi

# compile the numba kernels now (cached beside the sources), not in the user's first `harness prune`
.venv/bin/python -m methods.warmup
.venv/bin/harness fetch bonsai-7k bonsai-7k-mini luigi --weights
.venv/bin/harness fetch grape-small playbot ||
  echo "setup: grape-small/playbot are not available here (no mirror folder, no access to GitHub); runs skip them"
