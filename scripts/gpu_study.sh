#!/bin/bash
# The study's GPU checks and benchmarks, on a GPU machine running the project from source (Python 3.12,
# no registries). Prepare the checkout first, where registries are: scripts/gpu_prepare.sh (wheels,
# EGL libraries, luigi + grape-small + LPIPS weights, ~59 MiB, git-ignored). Then, in the repository
# root of the GPU machine:
#
#   scripts/gpu_study.sh tests      # the torch forms against the CPU forms on CUDA (~1 min)
#   scripts/gpu_study.sh default    # calibrate, then the default study's protocol on the two scenes on CUDA,
#                                   # checked against a CPU run on grape-small (~5 min)
#   scripts/gpu_study.sh full       # full.yaml (1024 px) on the two scenes on CUDA, no check (minutes)
#   scripts/gpu_study.sh all        # the three in turn
#
# Results go to $OUT/bench (the device tool's $OUT; default runs/gpu): calibrate-cuda.{json,md},
# study-default-cuda.{json,md}, study-full-cuda.{json,md}, tests.txt. Copy them into results/bench to
# commit them (calibrate-cuda.json there is what `harness plan --estimate` reads for one GPU).
set -uo pipefail
cd "$(dirname "$0")/.."
R=$(pwd)
OUT=${OUT:-$R/runs/gpu}
WORKERS=${WORKERS:-8}
mkdir -p "$OUT/bench"

# -- from source: wheels into .site, the EGL loader from .gl, the carried cache (../shared/gpu/README.md)
for f in "$R"/.gl/*.deb; do [ -e "$f" ] && dpkg -x "$f" /; done
ldconfig 2>/dev/null || true
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target "$R/.site" \
  "$R"/.whl/*.whl || { echo "gpu_study: the wheels in .whl/ did not install (run scripts/gpu_prepare.sh)"; exit 2; }
export PYTHONPATH=$R/.site:$R HARNESS_CACHE=$R/.cache-harness HARNESS_SHARED_DATA=$R/.cache-harness/data \
  PYTHONUNBUFFERED=1
python3 - <<'PY' || exit 2
import moderngl, torch
ctx = moderngl.create_standalone_context(backend="egl", require=330)
print("GL:", ctx.info["GL_RENDERER"], "| torch", torch.__version__, "| CUDA:",
      torch.cuda.get_device_name(0) if torch.cuda.is_available() else "none")
PY
harness() { python3 -m harness.cli "$@"; }

tests() {
  timeout 300 python3 -m pytest -q -p no:cacheprovider -rs tests/test_metrics_torch_forms.py \
    tests/test_batched_views.py tests/test_metrics_mpeg.py tests/test_metrics_ssim.py tests/test_metrics_lpips.py \
    tests/test_gl_renderer.py tests/test_gl_batch.py tests/test_device_workers.py tests/test_local_executor.py \
    tests/test_significance_batched.py tests/test_virtualrig.py 2>&1 | tee "$OUT/bench/tests.txt" | tail -15
}
default() {
  timeout 120 harness bench calibrate --device cuda --out "$OUT/bench"
  timeout 420 harness bench study --device cuda ctc_configs/default.yaml --scenes luigi,grape-small \
    --check grape-small --workers "$WORKERS" --out "$OUT/bench"
}
full() {
  timeout 570 harness bench study --device cuda ctc_configs/full.yaml --scenes luigi,grape-small --check none \
    --workers "$WORKERS" --out "$OUT/bench"
}

case "${1:-default}" in
  tests) tests ;;
  default) default ;;
  full) full ;;
  all) tests; default; full ;;
  *) echo "usage: scripts/gpu_study.sh [tests|default|full|all]"; exit 2 ;;
esac
