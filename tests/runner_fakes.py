"""Small, fast stand-ins for the runner's tests: a point-splat renderer, a circle rig, fake pruners.

Importing this module registers the pruners ``fake-norm`` (camera-agnostic, score = −‖mean‖; its
``unused`` parameter does not change the scores, so two variants give identical keep masks),
``fake-aware`` (needs cameras), ``fake-device`` (declares ``uses_device``: fake-norm's scores), ``fake-broken``
(always raises), and for the executor tests
``fake-slow`` (fake-norm's scores after ``seconds`` of sleep) and ``fake-raise`` (raises); these two
append ``<pid>`` to the file ``marker`` at every attempt, so a test in another process sees each
attempt and which worker runs it. Call counters live in :data:`CALLS` (meaningful for in-process runs).
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from harness.core.cameras import Camera
from harness.core.params import Params, param
from harness.core.scene import base_colors, opacities
from harness.run.toolkit import Toolkit
from methods.registry import register_pruner

CALLS: Counter = Counter()


@dataclass(frozen=True)
class FakeParams(Params):
    unused: int = param(0, doc="changes nothing")


@register_pruner("fake-norm", params=FakeParams)
def fake_norm(scene, ctx):
    """Keep splats near the origin: score = −‖mean‖."""
    CALLS["score:fake-norm"] += 1
    return -np.linalg.norm(scene.means.astype(np.float64), axis=1)


@register_pruner("fake-aware", needs=("cameras",))
def fake_aware(scene, ctx):
    """Camera-aware stand-in: opacity."""
    CALLS["score:fake-aware"] += 1
    return opacities(scene).astype(np.float64)


@register_pruner("fake-device", uses_device=True)
def fake_device(scene, ctx):
    """A pruner that computes on the run's device (here: fake-norm's scores, on any device)."""
    CALLS["score:fake-device"] += 1
    return -np.linalg.norm(scene.means.astype(np.float64), axis=1)


@register_pruner("fake-broken")
def fake_broken(scene, ctx):
    """Always fails (the run must record it and go on)."""
    raise RuntimeError("this pruner is broken on purpose")


@dataclass(frozen=True)
class MarkerParams(Params):
    marker: str = param("", doc="file that gets one line '<pid>' per attempt (empty: none)")
    seconds: float = param(0.0, ge=0, doc="sleep before scoring")


def _attempt(marker: str) -> None:
    import os

    if marker:
        with open(marker, "a") as f:
            f.write(f"{os.getpid()}\n")


@register_pruner("fake-slow", params=MarkerParams)
def fake_slow(scene, ctx):
    """fake-norm's scores, after ``seconds`` of sleep (a window to kill its worker in)."""
    import time

    _attempt(ctx.params.marker)
    time.sleep(ctx.params.seconds)
    return -np.linalg.norm(scene.means.astype(np.float64), axis=1)


@register_pruner("fake-raise", params=MarkerParams)
def fake_raise(scene, ctx):
    """Raises on every attempt (a deterministic failure)."""
    _attempt(ctx.params.marker)
    raise ValueError("fake-raise fails on purpose")


@dataclass
class MarkerTask:
    """A task description for :func:`escaping_task` / :func:`crashing_task` (``path``: the marker file)."""

    path: str
    label: str = "marker"

    def failed(self, message: str) -> dict:
        return {"error": message}


def escaping_task(task, scene=None):
    """A stage function whose exception is not caught inside (as a bug would): records the attempt."""
    _attempt(task.path)
    raise KeyError("escaped on purpose")


def crashing_task(task, scene=None):
    """A stage function that kills its own process at every attempt (a deterministic segfault)."""
    import os

    _attempt(task.path)
    os._exit(3)


def disk_full_task(task, scene=None):
    """A stage function whose output write finds the disk full (ENOSPC from the writer)."""
    import errno

    from harness.core.errors import task_error
    from harness.io.files import atomic_write_with

    def full(tmp):
        raise OSError(errno.ENOSPC, "No space left on device")

    try:
        atomic_write_with(Path(task.path) / f"{task.label}.bin", full)
    except Exception as err:  # as the run's tasks record their errors
        return task.failed(task_error(err))
    return {"label": task.label}


class PointRenderer:
    """Each splat adds opacity·colour to the pixel its centre projects to; sensitive to every splat."""

    name = "fake-points"

    def render(self, scene, camera: Camera, background=(0.0, 0.0, 0.0)) -> np.ndarray:
        CALLS["render"] += 1
        h, w = camera.height, camera.width
        p = scene.means.astype(np.float64) @ camera.rotation.T + camera.translation
        ok = p[:, 2] > 0.2
        u = np.floor(camera.fx * p[ok, 0] / p[ok, 2] + camera.cx).astype(int)
        v = np.floor(camera.fy * p[ok, 1] / p[ok, 2] + camera.cy).astype(int)
        inside = (u >= 0) & (u < w) & (v >= 0) & (v < h)
        img = np.zeros((h, w, 3), np.float64)
        col = (base_colors(scene) * opacities(scene)[:, None])[ok][inside]
        np.add.at(img, (v[inside], u[inside]), col)
        img = 1.0 - np.exp(-img) + np.asarray(background) * np.exp(-img)
        return img.astype(np.float32)

    def close(self) -> None:
        pass


def make_renderer(name: str, device: str):
    return PointRenderer()


def cpu_metrics(names, device: str):
    """The metric suite on the CPU whatever the run's device (a GPU run's routing, tested on the CPU)."""
    from harness.run.toolkit import make_metrics

    return make_metrics(names, "cpu")


def make_rig(rig, scene, *, kind, dataset, n_train, n_test, longest_side, aspect, seed):
    """Cameras on a circle of radius 5 around the origin; every other one held out until n_test."""
    n = n_train + n_test
    w, h = longest_side, max(1, round(longest_side / (aspect or 4 / 3)))
    cams = [Camera.look_at((5 * math.cos(2 * math.pi * i / n + seed), 0.5, 5 * math.sin(2 * math.pi * i / n + seed)),
                           (0, 0, 0), fov_y_deg=40, width=w, height=h, name=f"cam{i:02d}") for i in range(n)]
    held = set(list(range(0, n, 2))[:n_test])
    return "circle", [c for i, c in enumerate(cams) if i not in held], [c for i, c in enumerate(cams) if i in held]


def toolkit(**overrides) -> Toolkit:
    base = dict(make_rig=make_rig, make_renderer=make_renderer, imports=("tests.runner_fakes",), preload=(),
                renderer_modules=("tests.runner_fakes",), rig_modules=("tests.runner_fakes",))
    return Toolkit(**{**base, **overrides})


def pid_task(task, scene=None):
    """A stage function that reports which process ran it."""
    import os

    return {"pid": os.getpid(), "label": task.label}


def write_two_scenes(folder) -> dict[str, str]:
    """Two small random scenes ``s0`` (300 splats) and ``s1`` (500) as .ply files: {name: path}."""
    from harness.io.scenes import write_scene
    from tests.scene_factory import random_scene

    paths = {}
    for i, n in enumerate((300, 500)):
        p = folder / f"s{i}.ply"
        write_scene(random_scene(n, sh_degree=1, seed=i), p)
        paths[f"s{i}"] = str(p)
    return paths
