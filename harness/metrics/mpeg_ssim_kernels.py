"""The numba kernels of :mod:`.mpeg_ssim`: the tool's SSIM / OM-SSIM per pixel, only where it can differ from 1.

Each output pixel runs the tool's arithmetic (metric.cpp, see :mod:`.mpeg_ssim`): the 121 taps in its
order (row offset j outer, column offset i inner), each accumulator a separate running sum, no fused
multiply-add, no reassociation. Runs of neighbouring pixels of a row are computed together, tap by
tap over the whole run (vectorisable), which changes no pixel's sequence of roundings. Rows run in
parallel, each writing its pixels into per-pixel maps; :func:`ordered_sum` then adds the maps in
pixel order, as the tool's running sum does, so the thread count changes no bit.

What is *not* computed, and why the value is known exactly:

* **Equal windows** (the two padded planes agree on all 121 taps): μa = μb, σa² = σb² = σab (the
  same operations on the same numbers), so ``(2μaμb + C1)(2σab + C2)`` and
  ``(μa² + μb² + C1)(σa² + σb² + C2)`` are the same number (2x = x + x exactly) and SSIM is exactly 1,
  masked or not. :func:`differs` flags, besides unequal taps, values whose square could leave the
  normal double range (then 2·x² and x² + x² may round apart), so those windows are computed.
* **Masked, no mask in the window**: the mask weight is Σ w·0 = 0 < 0.5, the pixel is skipped.
* **Masked, mask everywhere in the window**: every tap weight w·1 is w, so the masked first-pass sums
  Σ (w·m)·P are the unmasked ones (:func:`_full_run` keeps μb's) and the weight is the constant
  Σ w·1 (:func:`ssim_maps`); only the second, centred pass is computed.
"""

from __future__ import annotations

import numba as nb
import numpy as np

WINDOW = 11
C1 = (0.01 * 255.0) * (0.01 * 255.0)
C2 = (0.03 * 255.0) * (0.03 * 255.0)
MASK_THRESHOLD = 0.5


@nb.njit(cache=True, nogil=True)
def window_count(flag, h, width):
    """``out[y, x] = Σ flag[y:y + 11, x:x + 11]`` of a padded ``(h + 10, width + 10)`` 0/1 plane
    (running box sums, rows then columns), int32 ``(h, width)``."""
    rows = flag.shape[0]
    across = np.zeros((rows, width), np.int32)
    for r in range(rows):
        c = 0
        for i in range(WINDOW - 1):
            c += flag[r, i]
        for x in range(width):
            c += flag[r, x + WINDOW - 1]
            across[r, x] = c
            c -= flag[r, x]
    out = np.empty((h, width), np.int32)
    col = np.zeros(width, np.int32)
    for r in range(WINDOW - 1):
        col += across[r]
    for y in range(h):
        col += across[y + WINDOW - 1]
        out[y] = col
        col -= across[y]
    return out


@nb.njit(cache=True, nogil=True)
def differs(pa, pb):
    """0/1 per padded pixel: 1 where the planes differ, or where the value is not 0 and not within
    1e-100..1e100 in magnitude (not finite, or its square near the edge of the double range)."""
    out = np.empty(pa.shape, np.uint8)
    for y in range(pa.shape[0]):
        for x in range(pa.shape[1]):
            a = pa[y, x]
            m = abs(a)
            same = a == pb[y, x] and (a == 0.0 or (m > 1e-100 and m < 1e100))
            out[y, x] = 0 if same else 1
    return out


@nb.njit(cache=True, nogil=True)
def _runs(row):
    """``(n, 2)``: start and end (exclusive) of each run of True in a bool row."""
    w = row.shape[0]
    out = np.empty((w // 2 + 1, 2), np.int64)
    n = 0
    x = 0
    while x < w:
        if row[x]:
            x1 = x
            while x1 < w and row[x1]:
                x1 += 1
            out[n, 0] = x
            out[n, 1] = x1
            n += 1
            x = x1
        else:
            x += 1
    return out[:n]


@nb.njit(cache=True, nogil=True)
def _window_run(p, y, x0, x1, w, out, mu):
    """For x in [x0, x1): ``out[x − x0] = Σ_j Σ_i w[i, j]·P[y + j, x + i]`` (``mu`` None: the window
    mean), else ``Σ_j Σ_i (w[i, j]·(P − μ))·(P − μ)`` with ``μ = mu[x − x0]`` (the spread)."""
    out[:] = 0.0
    for j in range(WINDOW):
        r = p[y + j]
        for i in range(WINDOW):
            wt = w[i, j]
            if mu is None:  # decided when compiled: one specialisation per form
                for x in range(x0, x1):
                    out[x - x0] += wt * r[x + i]
            else:
                for x in range(x0, x1):
                    d = r[x + i] - mu[x - x0]
                    out[x - x0] += wt * d * d


@nb.njit(cache=True, nogil=True)
def fill_moments(p, w, h, width, mu, s):
    """Window mean and spread of every pixel of a padded plane into ``mu``, ``s`` (h, width)."""
    for y in range(h):
        _window_run(p, y, 0, width, w, mu[y], None)
        _window_run(p, y, 0, width, w, s[y], mu[y])


@nb.njit(cache=True, nogil=True)
def _full_run(pa, mu_a, s_aa, pb, y, x0, x1, w, out, ok, mu_b_sums):
    """SSIM (computeSSIM) of pixels x0..x1 of row y, the first plane's moments given; μb kept in
    ``mu_b_sums`` (the masked form's first-pass sum where the mask fills the window)."""
    n = x1 - x0
    mu_b = mu_b_sums[x0:x1]
    _window_run(pb, y, x0, x1, w, mu_b, None)
    s_bb = np.zeros(n)
    s_ab = np.zeros(n)
    for j in range(WINDOW):
        ra = pa[y + j]
        rb = pb[y + j]
        for i in range(WINDOW):
            wt = w[i, j]
            for x in range(n):
                da = ra[x0 + x + i] - mu_a[x]
                db = rb[x0 + x + i] - mu_b[x]
                s_bb[x] += wt * db * db
                s_ab[x] += wt * da * db
    for x in range(n):
        num = (2 * mu_a[x] * mu_b[x] + C1) * (2 * s_ab[x] + C2)
        den = (mu_a[x] * mu_a[x] + mu_b[x] * mu_b[x] + C1) * (s_aa[x] + s_bb[x] + C2)
        ok[x0 + x] = den > 0
        out[x0 + x] = num / den if den > 0 else 0.0


@nb.njit(cache=True, nogil=True)
def _masked_pass(pa, pb, pm, y, x0, x1, w, mu_a, mu_b, s0, s1, s2, centred):
    """A pass of computeMaskedSSIM over pixels x0..x1, tap weight ``w·m``: the first (``centred``
    False) sums (w·m)·Pa, (w·m)·Pb and w·m into s0, s1, s2; the second sums ((w·m)·da)·da,
    ((w·m)·db)·db and ((w·m)·da)·db, with ``d = P − μ``."""
    s0[:] = 0.0
    s1[:] = 0.0
    s2[:] = 0.0
    for j in range(WINDOW):
        ra, rb, rm = pa[y + j], pb[y + j], pm[y + j]
        for i in range(WINDOW):
            wt = w[i, j]
            for x in range(x1 - x0):
                wm = wt * rm[x0 + x + i]
                if centred:
                    da = ra[x0 + x + i] - mu_a[x]
                    db = rb[x0 + x + i] - mu_b[x]
                    s0[x] += wm * da * da
                    s1[x] += wm * db * db
                    s2[x] += wm * da * db
                else:
                    s0[x] += wm * ra[x0 + x + i]
                    s1[x] += wm * rb[x0 + x + i]
                    s2[x] += wm


@nb.njit(cache=True, nogil=True)
def _masked_ratio(pa, pb, pm, y, x0, x1, w, mu_a, mu_b, msum, out, ok):
    """OM-SSIM of pixels x0..x1 from the first pass' sums: means divided by the weight, the centred
    second pass, the ratio; ``ok`` False where the weight is under 0.5 (skipped) or den ≤ 0."""
    n = x1 - x0
    for x in range(n):  # dividing a skipped pixel too is harmless: it is never read
        mu_a[x] /= msum[x] if msum[x] >= MASK_THRESHOLD else 1.0
        mu_b[x] /= msum[x] if msum[x] >= MASK_THRESHOLD else 1.0
    s_aa, s_bb, s_ab = np.empty(n), np.empty(n), np.empty(n)
    _masked_pass(pa, pb, pm, y, x0, x1, w, mu_a, mu_b, s_aa, s_bb, s_ab, True)
    for x in range(n):
        ok[x0 + x] = False
        out[x0 + x] = 0.0
        if msum[x] < MASK_THRESHOLD:
            continue
        saa = s_aa[x] / msum[x]
        sbb = s_bb[x] / msum[x]
        sab = s_ab[x] / msum[x]
        num = (2 * mu_a[x] * mu_b[x] + C1) * (2 * sab + C2)
        den = (mu_a[x] * mu_a[x] + mu_b[x] * mu_b[x] + C1) * (saa + sbb + C2)
        if den > 0:
            ok[x0 + x] = True
            out[x0 + x] = num / den


@nb.njit(cache=True, nogil=True)
def _masked_row(pa, pb, pm, y, w, diff, count, mu_a_sums, mu_b_sums, full_weight, out, ok):
    """OM-SSIM of row y, each pixel by its window's mask count (see the module docstring)."""
    width = out.shape[0]
    full = WINDOW * WINDOW
    partial = (count > 0) & (count < full)
    for x in range(width):
        equal_inside = count[x] == full and not diff[x]
        out[x] = 1.0 if equal_inside else 0.0
        ok[x] = equal_inside
    runs = _runs(partial & ~diff)  # equal windows: exactly 1 where the weight reaches 0.5
    for k in range(runs.shape[0]):
        x0, x1 = runs[k, 0], runs[k, 1]
        msum = np.empty(x1 - x0)
        _window_run(pm, y, x0, x1, w, msum, None)  # Σ w·m: the maskSum's taps, its order
        for x in range(x0, x1):
            if msum[x - x0] >= MASK_THRESHOLD:
                out[x] = 1.0
                ok[x] = True
    runs = _runs(partial & diff)
    for k in range(runs.shape[0]):
        x0, x1 = runs[k, 0], runs[k, 1]
        n = x1 - x0
        mu_a, mu_b, msum = np.empty(n), np.empty(n), np.empty(n)
        _masked_pass(pa, pb, pm, y, x0, x1, w, mu_a, mu_b, mu_a, mu_b, msum, False)  # means not read: first pass
        _masked_ratio(pa, pb, pm, y, x0, x1, w, mu_a, mu_b, msum, out, ok)
    runs = _runs((count == full) & diff)
    for k in range(runs.shape[0]):
        x0, x1 = runs[k, 0], runs[k, 1]
        msum = np.full(x1 - x0, full_weight)
        _masked_ratio(pa, pb, pm, y, x0, x1, w, mu_a_sums[x0:x1].copy(), mu_b_sums[x0:x1].copy(), msum, out, ok)


@nb.njit(cache=True, nogil=True, parallel=True)
def ssim_maps(pa, mu_all, s_all, known, pb, pm, w, diff, count, masked, full, full_ok, om, om_ok):
    """Per pixel, rows in parallel: SSIM into ``full`` and, when ``masked`` (``pm`` the padded 0/1
    mask, ``count`` its window counts), OM-SSIM into ``om``; ``*_ok`` say which pixels count.

    ``diff``: windows where the planes differ (:func:`differs`, :func:`window_count` > 0); only those
    are computed. The first plane's moments are filled into ``mu_all``/``s_all`` where ``known`` is
    False and read where it is True (a reference's moments, kept for the next image)."""
    h, width = full.shape
    full_weight = 0.0  # Σ w·1 in the taps' order: the mask weight of a window the mask fills
    for j in range(WINDOW):
        for i in range(WINDOW):
            full_weight += w[i, j] * 1.0
    for y in nb.prange(h):
        full_y, full_ok_y, diff_y = full[y], full_ok[y], diff[y]
        mu_b_sums = np.zeros(width)
        for x in range(width):
            full_y[x] = 1.0
            full_ok_y[x] = True
        runs = _runs(diff_y)
        for k in range(runs.shape[0]):
            x0, x1 = runs[k, 0], runs[k, 1]
            if not known[y, x0:x1].all():
                _window_run(pa, y, x0, x1, w, mu_all[y, x0:x1], None)
                _window_run(pa, y, x0, x1, w, s_all[y, x0:x1], mu_all[y, x0:x1])
                known[y, x0:x1] = True
            _full_run(pa, mu_all[y, x0:x1], s_all[y, x0:x1], pb, y, x0, x1, w, full_y, full_ok_y, mu_b_sums)
        if masked:
            _masked_row(pa, pb, pm, y, w, diff_y, count[y], mu_all[y], mu_b_sums, full_weight, om[y], om_ok[y])


@nb.njit(cache=True, nogil=True)
def ordered_sum(values, ok):
    """(Σ of the counted values in row-major pixel order, their count): the tool's running sum."""
    total = 0.0
    count = 0
    for y in range(values.shape[0]):
        for x in range(values.shape[1]):
            if ok[y, x]:
                total += values[y, x]
                count += 1
    return total, count
