"""One-dimensional correlation with a symmetric kernel and zeros beyond the edges, as scipy computes it.

:func:`correlate_symmetric` is ``scipy.ndimage.correlate1d(x, taps, axis, mode="constant", cval=0)``
bit for bit for float64 data and symmetric taps ``w`` of odd length ``2r + 1``: scipy's symmetric loop
evaluates, for every output sample,

    y_i = x_i·w_r + Σ_{k=r..1} (x_{i−k} + x_{i+k})·w_{r−k}      (x = 0 outside the array)

left to right, one rounding per operation, and numpy's element-wise operations round the same way.
Computed in blocks of about :data:`BLOCK_BYTES` (a block's padded copy and its temporaries stay in
the cache). Measured on a stack of nine 1024x768 planes: along the rows a third of scipy's time
(41 vs 126 ms; scipy walks each column on its own), along the last axis 1.5 times it (44 vs 29 ms),
both passes together 85 vs 155 ms; and scipy.ndimage, whose import alone costs 0.1–0.3 s, is never
imported.
"""

from __future__ import annotations

import numpy as np

#: bytes of input per block (its zero-padded copy); beyond ~1 MiB blocks leave the L2 cache
BLOCK_BYTES = 1 << 20


def correlate_symmetric(x, taps, axis: int = -1) -> np.ndarray:
    """``x`` (float64) correlated along ``axis`` with the symmetric odd-length ``taps`` (module
    docstring); a new C-contiguous float64 array of ``x``'s shape."""
    w = np.asarray(taps, np.float64)
    r = len(w) // 2
    if w.ndim != 1 or len(w) % 2 == 0 or not np.array_equal(w, w[::-1]):
        raise ValueError("taps must be a 1-D symmetric kernel of odd length")
    x = np.ascontiguousarray(x, np.float64)
    axis = axis % x.ndim
    n = x.shape[axis]
    lead, trail = int(np.prod(x.shape[:axis])), int(np.prod(x.shape[axis + 1:]))
    src = x.reshape(lead, n, trail)
    out = np.empty_like(src)
    step = max(1, BLOCK_BYTES // (8 * max((n + 2 * r) * trail, 1)))  # leading rows per block
    padded = np.zeros((min(step, lead), n + 2 * r, trail))  # its first and last r rows stay zero
    term = np.empty((min(step, lead), n, trail))
    for a in range(0, lead, step):
        b = min(a + step, lead)
        pad, tmp, dst = padded[: b - a], term[: b - a], out[a:b]
        pad[:, r:r + n] = src[a:b]
        np.multiply(pad[:, r:r + n], w[r], out=dst)
        for k in range(r, 0, -1):
            np.add(pad[:, r - k:r - k + n], pad[:, r + k:r + k + n], out=tmp)
            tmp *= w[r - k]
            dst += tmp
    return out.reshape(x.shape)
