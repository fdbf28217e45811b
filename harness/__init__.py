"""Evaluation and benchmark harness for camera-agnostic 3DGS pruning (MPEG CTC style)."""

__version__ = "0.1.0"
