#!/usr/bin/env bash
# Idempotent set-up on a fresh Debian machine (root, Python 3.11, no GPU, package registries only):
#   1. system packages for headless OpenGL through EGL (Mesa llvmpipe)      -- skipped when present
#   2. a virtual environment .venv with this package and its test extra     -- skipped when up to date
#   3. the registry scenes and the LPIPS-VGG weights (`harness fetch`)      -- verified, no-op when present
# A second call reuses everything and takes a few seconds.
set -euo pipefail
cd "$(dirname "$0")"

PY=${PYTHON:-python3.11}
command -v "$PY" >/dev/null 2>&1 || PY=python3

egl_ok() { ldconfig -p 2>/dev/null | grep -q 'libEGL_mesa.so' && ls /usr/lib/*/dri/swrast_dri.so >/dev/null 2>&1; }
if ! egl_ok; then
  echo "setup: installing EGL/Mesa system packages"
  SUDO=""; [ "$(id -u)" = 0 ] || SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq libegl1 libegl-mesa0 libgl1-mesa-dri >/dev/null
fi

stamp=.venv/.installed-$(sha256sum pyproject.toml | cut -c1-16)
if [ ! -f "$stamp" ]; then
  echo "setup: creating .venv and installing the package (torch comes from the machine's wheel store)"
  [ -x .venv/bin/python ] || "$PY" -m venv .venv
  .venv/bin/python -m pip install -q --upgrade pip
  .venv/bin/python -m pip install -q -e ".[test]"
  rm -f .venv/.installed-*
  touch "$stamp"
fi

.venv/bin/harness fetch
