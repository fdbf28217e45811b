"""Decoding helpers shared by the quantised splat formats (``.splat``, compressed.ply, spz, ksplat).

* Alpha bytes: every format here stores *linear* opacity ``a = sigmoid(opacity)`` in a byte
  ``b ≈ 255·a``. Decoded as ``logit(clip(b/255, ¼/255, 1 − ¼/255))``: bytes 0 and 255 would give
  ∓inf, so they are clamped a quarter quantisation step inside (opacity ¼/255 keeps every pixel of
  the splat below the renderers' 1/255 alpha cut-off, as b = 0 implies).
* Unsigned normalised fields: ``unorm(v, shift, bits) = ((v >> shift) & (2^bits − 1)) / (2^bits − 1)``.
* "Smallest three" quaternions: the largest-magnitude component is left out (its index is stored)
  and recovered as ``sqrt(max(0, 1 − Σ others²))`` (non-negative: q and −q are the same rotation);
  the other three are stored in ascending component order. :func:`smallest_three` places them.
* Size checks: :func:`need` turns "the header promises more than the bytes hold" into one line.
"""

from __future__ import annotations

import numpy as np

from harness.core.errors import InputError

_ALPHA_EPS = 0.25 / 255.0
_ALPHA_OF_BYTE = np.clip(np.arange(256, dtype=np.float64) / 255.0, _ALPHA_EPS, 1.0 - _ALPHA_EPS)
#: byte -> opacity logit, computed in float64 and rounded once to float32
LOGIT_OF_ALPHA_BYTE = np.log(_ALPHA_OF_BYTE / (1.0 - _ALPHA_OF_BYTE)).astype(np.float32)


def round_half_away(x: np.ndarray) -> np.ndarray:
    """C's ``round``/``std::round`` (half away from zero), exact in the input's dtype.

    ``floor(x + 0.5)`` is not: for the float32 just below 0.5, ``x + 0.5`` rounds up to 1.0. Here the
    fraction ``x − trunc(x)`` is exact, so only a true half rounds away."""
    x = np.asarray(x)
    t = np.trunc(x)
    return t + np.where(np.abs(x - t) >= 0.5, np.sign(x), 0).astype(x.dtype)


def unorm(values: np.ndarray, shift: int, bits: int) -> np.ndarray:
    """The ``bits``-wide field at ``shift`` of unsigned integers, as float64 in [0, 1]."""
    top = (1 << bits) - 1
    return ((values.astype(np.uint32) >> np.uint32(shift)) & np.uint32(top)).astype(np.float64) / top


def smallest_three(largest: np.ndarray, others: np.ndarray) -> np.ndarray:
    """(N, 4) quaternions from the index of the left-out component and the other three (N, 3).

    Component order is the caller's (w, x, y, z or x, y, z, w); ``others`` are in ascending
    component order with the largest skipped. The largest is ``sqrt(max(0, 1 − Σ others²))``.
    """
    n = len(largest)
    largest = largest.astype(np.int64)
    slots = np.array([[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]])[largest]
    q = np.empty((n, 4))
    q[np.arange(n)[:, None], slots] = others
    q[np.arange(n), largest] = np.sqrt(np.maximum(0.0, 1.0 - (others * others).sum(1)))
    return q


def xyzw_to_wxyz(q: np.ndarray) -> np.ndarray:
    return q[:, [3, 0, 1, 2]]


def log_of_linear(scale: np.ndarray) -> np.ndarray:
    """``log(scale)``; zero gives −inf and a negative value NaN, which scene validation reports."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.log(scale.astype(np.float64))


def need(source, available: int, required: int, what: str) -> None:
    """InputError unless ``available >= required`` bytes (checked before anything is allocated)."""
    if available < required:
        raise InputError(source, f"truncated or wrong count: {what} needs {required:,} bytes, "
                                 f"only {max(available, 0):,} present")
