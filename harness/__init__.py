"""Evaluation and benchmark harness for camera-agnostic 3DGS pruning (MPEG CTC style).

Layers (arrows point one way, checked by tests/test_layers.py)::

    cli, commands → run, benchmarks → report → methods → renderers, metrics → views, io → core

``methods`` (pruners) and ``renderers`` are top-level packages beside ``harness``; they import
``harness.core`` (and methods also ``harness.metrics`` and ``renderers``), never ``harness.run`` or
``harness.report``.
"""

__version__ = "0.1.0"
