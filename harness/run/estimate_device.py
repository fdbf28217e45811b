"""What a cold run of a config takes on **one GPU** beside a node's CPU cores, from the device's
calibration (``harness bench calibrate --device cuda`` → ``calibrate-cuda.json`` in the benchmark
folder); without one, nothing is guessed: the estimate says the GPU time is not measured.

The counts are :func:`harness.run.estimate.estimate`'s, costed twice: with the GPU's units (its
render and metric passes, seconds of the device) and with the CPU's (reading, selection and
camera-free scoring stay on the CPU). The model, stage by stage as the runner runs them:

as the local pool runs a GPU run: CPU tasks on the CPU workers, the device's tasks on its device
workers (:mod:`harness.run.executors.device`), the two pools side by side:

* ``load`` and ``prune`` in the driver, serial, CPU units;
* ``score``: camera-free pruners on the CPU workers, i.e. the cores (``core_s / (cores · e)``), and
  camera-aware ones on the device worker(s), one after another on the GPU (their training renders at
  the GPU's render units × the CPU benchmark's multiple ``k_m`` of a training render: an assumption,
  the note says so); the pools run together, so the stage takes the longer of the two. A camera-free
  pruner that computes on the device (the virtual rig) is costed at its CPU units on the cores: an
  upper bound, the calibration has no unit for it;
* ``render_ref`` and ``render+metrics`` on the device worker(s), serial on the GPU (every image's
  render and metric passes at the GPU's units, per view its reference features): the device does one
  thing at a time, so several device workers overlap only their CPU share, which this leaves out;

plus :data:`harness.run.estimate.STARTUP_S` per pool stage.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

from harness.run.estimate import STARTUP_S, estimate
from harness.run.unit_costs import COVERAGE_UNITS, UnitCosts
from harness.run.view_coverage import Coverage

CALIBRATION = "calibrate-cuda.json"
GPU_UNITS = ("render_splat", "render_px", "lpips_px", "lpips_ref_px", "ssim_px", "psnr_px")


def read_calibration(folder: Path) -> dict | None:
    """The GPU's calibration in ``folder`` (None: absent or unreadable)."""
    try:
        doc = json.loads((Path(folder) / CALIBRATION).read_text())
        return doc if all(isinstance(doc["units"].get(k), (int, float)) for k in GPU_UNITS) else None
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return None


def one_gpu(config, infos, folder: Path, cpu: UnitCosts, cores: int, efficiency: float) -> dict:
    """``{"measured": False, "note"}`` without a calibration, else the projected wall seconds on one
    GPU and ``cores`` CPU cores, per stage (module docstring), with what they stand on."""
    cal = read_calibration(folder)
    if cal is None:
        return {"measured": False,
                "note": f"GPU time not measured: no {CALIBRATION} in {folder} (`harness bench calibrate --device "
                        "cuda --out results/bench` on a GPU machine writes it)"}
    # the coverage units and view when the device's calibration measured them, else the plain model (draw_splat 0)
    covered = {k: float(cal["units"].get(k, 0.0)) for k in COVERAGE_UNITS}
    seen = Coverage(**cal["seen"]) if covered["draw_splat"] and isinstance(cal.get("seen"), dict) else cpu.seen
    gpu = replace(cpu, **{k: float(cal["units"][k]) for k in GPU_UNITS}, sources={}, notes=[],
                  pack_splat=float(cal["units"].get("pack_splat", 0.0)), **covered, seen=seen,
                  aware={k: v for k, v in cpu.aware.items() if v[1] != "rig"})  # a virtual rig: CPU units, as below
    free = replace(cpu, render_splat=0.0, render_px=0.0, pack_splat=0.0, aware={},  # camera-free scoring, CPU units
                   **dict.fromkeys(COVERAGE_UNITS, 0.0))
    on_gpu, on_cpu = estimate(config, infos, gpu).stages, estimate(config, infos, free).stages
    aware_s = on_gpu["score"].core_s - on_cpu["score"].core_s
    stages = {"load": on_cpu["load"].core_s, "prune": on_cpu["prune"].core_s,
              "score": STARTUP_S + max(on_cpu["score"].core_s / (cores * efficiency), aware_s),
              "render_ref": STARTUP_S + on_gpu["render_ref"].core_s,
              "render+metrics": STARTUP_S + on_gpu["render+metrics"].core_s}
    return {"measured": True, "wall_s": sum(stages.values()), "stages_s": stages, "cores": cores,
            "device": cal.get("device_name", "GPU"), "source": f"{folder / CALIBRATION} ({cal.get('when', '')})",
            "note": "camera-aware scoring on the GPU costed with the CPU benchmark's multiple of a training render"}
