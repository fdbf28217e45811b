"""Waiting for a GL context's drawing without holding Python's GIL (:func:`wait_without_gil`)."""

from __future__ import annotations

import functools


def wait_without_gil() -> None:
    """Wait for the current context's drawing with ``glFinish`` called through ctypes, which releases
    the GIL while the driver works (llvmpipe rasterises in this call): other Python threads run
    meanwhile (``harness render`` encodes the previous view's PNG), whereas moderngl's read-back
    holds the GIL until the image is ready. Where no GL library loads, nothing (the read-back then
    waits, as before); the pixels are the same either way."""
    _gl_finish()()


@functools.lru_cache(maxsize=1)
def _gl_finish():
    """``glFinish`` of GLVND's dispatcher (else of the vendor's libGL) as a ctypes function."""
    import ctypes

    for name in ("libOpenGL.so.0", "libGL.so.1"):
        try:
            return ctypes.CDLL(name).glFinish
        except (OSError, AttributeError):
            continue
    return lambda: None
