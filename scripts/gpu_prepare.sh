#!/bin/bash
# Prepare this checkout for a GPU machine that has Python 3.12 with torch, numba, numpy, pandas, scipy,
# scikit-image and pytest but no package registry (scripts/gpu_study.sh runs there). Run here, in a
# checkout with registries, once; writes three git-ignored folders, about 61 MiB in all (the device
# tool carries at most 64 MiB):
#   .whl/            the wheels the project needs beyond that (moderngl, glcontext, bjontegaard, plyfile)
#   .gl/             the EGL loader libraries as Debian packages (the NVIDIA driver provides the rest)
#   .cache-harness/  laid out like ~/.cache/harness: luigi and grape-small (data/) and the LPIPS-VGG
#                    weights (weights/, 56 MiB); bonsai-7k does not fit, so the GPU study measures
#                    the two small scenes (scripts/gpu_study.sh --scenes)
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-.venv/bin/python}
SRC=${HARNESS_CACHE:-$HOME/.cache/harness}
SHARED=${HARNESS_SHARED_DATA:-../shared/data}
"$PY" -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
  --platform manylinux_2_28_x86_64 --platform manylinux_2_17_x86_64 --platform manylinux2014_x86_64 \
  --platform manylinux1_x86_64 -d .whl moderngl==5.13.0 glcontext==3.1.0 bjontegaard==1.3.0 plyfile==1.1.5
mkdir -p .gl
(cd .gl && apt-get download -q libegl1 libglvnd0 libopengl0 libgl1 libglx0 libgles2 >/dev/null)
mkdir -p .cache-harness/data .cache-harness/weights
cp "$SRC/data/luigi.ply" .cache-harness/data/
cp "$(ls "$SHARED/grape_small.ply" 2>/dev/null || echo "$SRC/data/grape_small.ply")" .cache-harness/data/
cp "$SRC/weights/lpips_vgg16_v0.1.pt" "$SRC/weights/lpips_vgg16_v0.1.pt.sha256" .cache-harness/weights/
du -sch .whl .gl .cache-harness
