"""Evaluation and benchmark harness for camera-agnostic 3DGS pruning (MPEG CTC style).

The Python API (:mod:`harness.api`, imported on first use so that ``import harness`` stays cheap)::

    scene = harness.load("bonsai-7k")                 # a path or a named dataset
    pruned = harness.prune(scene, ratio=0.3)          # .scene .mask .scores .tau .seconds
    harness.save(pruned.scene, "bonsai-30.ply")       # format by name, as `harness convert`
    cameras = harness.cameras(scene)                  # the views `harness render` renders
    images = harness.render(pruned.scene, cameras)    # (H, W, 3) float32 per camera
    harness.compare(a, b, metrics="mpeg")             # {"rgb_psnr": ..., ...}
    rows = harness.evaluate("ctc_configs/ci.yaml")    # a pandas DataFrame
    harness.methods()                                 # the registered pruners

Bad input raises :class:`HarnessError` with the one-line message the command line prints.

Layers (arrows point one way, checked by tests/test_layers.py)::

    cli, commands → api → run, benchmarks → report → methods → renderers, metrics → views, io → core

``methods`` (pruners) and ``renderers`` are top-level packages beside ``harness``; they import
``harness.core`` (and methods also ``harness.metrics`` and ``renderers``), never ``harness.run`` or
``harness.report``.
"""

__version__ = "0.1.0"

_API = ("Pruned", "cameras", "compare", "evaluate", "info", "load", "methods", "prune", "render", "save", "score")
__all__ = ["HarnessError", "Scene", *_API]


def __getattr__(name: str):
    if name in _API:
        import harness.api

        return getattr(harness.api, name)
    if name == "HarnessError":
        from harness.core.errors import HarnessError

        return HarnessError
    if name == "Scene":
        from harness.core.scene import GaussianScene

        return GaussianScene
    raise AttributeError(f"module 'harness' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))
