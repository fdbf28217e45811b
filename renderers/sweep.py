"""LightGaussian's per-splat significance Σ_pixels o·T of one view in a single front-to-back sweep:
no pixel pairs, no image, and the geometry projected in numba.

:mod:`renderers.pixel_pairs` enumerates every (pixel, splat) pair of a view, stores them grouped by
pixel, then composites them: on the virtual rig's views most of those pairs lie behind pixels that are
already opaque (luigi at 384 px: ~15 M pairs per view, of which ~3.5 M are composited before graphdeco's
early termination). Compositing is per pixel, so the same sums come from visiting the *splats* in
front-to-back order and, for each, the pixels of its footprint in row-major order, with one
transmittance per pixel:

    for splat j in depth order (stable, ties by scene index), pixel p in its box, row-major:
        skip p if it has stopped; g = e^power (float32, the α tests of pixel_pairs); α = min(0.99, o·g)
        early stop: if T_p·(1 − α) < 1e-4, p stops (j gets nothing there)
        S_j += o·T_p;  T_p ← T_p·(1 − α)

Every pixel sees the splats in the order the pair list gives it, and every splat sums its pixels in
the order the pair compositing visits them, so with the same projection the result is **bit for bit**
:func:`renderers.pixel_pairs.composite`'s ``opacity_t`` (``tests/test_sweep.py``). Early termination
is also where the time goes: a pixel that has stopped costs one load, and a run of
:data:`SEGMENT` stopped pixels in a row is skipped at once (a live-pixel count per row segment).

:func:`project` is :func:`renderers.projection.project_gaussians` without colours, in numba: the same
float32 operations in the same order (scalars rounded to float32 as torch does; ``s / z`` of a scalar
as torch's ``reciprocal(z)·s``), so it agrees with the torch projection to the last bit except where
``exp`` rounds differently (a splat's scale or opacity, ≤ 1 ulp): the visible set and depth order are
the same, the conics and opacities within float32 rounding (checked in the tests).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
import torch

from harness.core.cameras import Camera
from renderers.projection import DILATION, NEAR_Z, TILE, quats_to_rotmats, sigmoid
from renderers.reference import ALPHA_MAX, ALPHA_MIN, T_EARLY_STOP

Q_SLACK = 1e-5  # relative bound on float32's error in the quadratic form of the α test (~20× the ulps)
RECORD = 7  # floats of a projected splat's record: means2d x, y, conic a, b, c, radius, opacity
SEGMENT = 8  # pixels per row segment whose live count lets a sweep skip stopped pixels
_F = np.float32


@nb.njit(cache=True)
def _front(means, m, smax, rot, trans, fx, fy, cx, cy, lims, w, h, ids, xyz, cov, m2d):
    """First pass: the splats in front of the near plane whose footprint may reach the image, their
    view point, 2D covariance (a, b, c, det) and centre; returns their count. A splat is passed over
    when even a bound on its radius keeps it 16 px off the image: r = ⌈3√λ⌉ with λ ≤ a + c + 0.32
    (the 0.1 clamp) and a + c = ‖J W M‖²_F + 0.6 ≤ ‖J‖²_F·s_max² + 0.6 (W a rotation, ‖M‖₂ = s_max)."""
    one, half, dil = _F(1.0), _F(0.5), _F(DILATION)
    neg_fx = -fx
    jw = np.empty((2, 3), np.float32)
    t = np.empty((2, 3), np.float32)
    k = 0
    for i in range(means.shape[0]):
        m0, m1, m2 = means[i, 0], means[i, 1], means[i, 2]
        z = ((m0 * rot[2, 0] + m1 * rot[2, 1]) + m2 * rot[2, 2]) + trans[2]
        if not z > _F(NEAR_Z):
            continue
        x = ((m0 * rot[0, 0] + m1 * rot[0, 1]) + m2 * rot[0, 2]) + trans[0]
        y = ((m0 * rot[1, 0] + m1 * rot[1, 1]) + m2 * rot[1, 2]) + trans[1]
        tx = min(max(x / z, lims[0]), lims[1]) * z
        ty = min(max(y / z, lims[2]), lims[3]) * z
        rz = one / z
        zz = z * z
        j00, j02 = rz * fx, (tx * neg_fx) / zz
        j11, j12 = rz * fy, (ty * -fy) / zz
        mx = ((x * fx) / z + cx) - half
        my = ((y * fy) / z + cy) - half
        jf2 = (np.float64(j00) ** 2 + np.float64(j02) ** 2) + (np.float64(j11) ** 2 + np.float64(j12) ** 2)
        rb = 3.0 * math.sqrt(jf2 * np.float64(smax[i]) ** 2 + 0.92) * 1.001 + 2.0 + TILE
        if mx + rb < 0.0 or my + rb < 0.0 or mx - rb > w + TILE or my - rb > h + TILE:
            continue
        for c in range(3):
            jw[0, c] = (j00 * rot[0, c] + _F(0.0) * rot[1, c]) + j02 * rot[2, c]
            jw[1, c] = (_F(0.0) * rot[0, c] + j11 * rot[1, c]) + j12 * rot[2, c]
        for r in range(2):
            for c in range(3):
                t[r, c] = (jw[r, 0] * m[i, 0, c] + jw[r, 1] * m[i, 1, c]) + jw[r, 2] * m[i, 2, c]
        a = ((t[0, 0] * t[0, 0] + t[0, 1] * t[0, 1]) + t[0, 2] * t[0, 2]) + dil
        b = (t[0, 0] * t[1, 0] + t[0, 1] * t[1, 1]) + t[0, 2] * t[1, 2]
        c = ((t[1, 0] * t[1, 0] + t[1, 1] * t[1, 1]) + t[1, 2] * t[1, 2]) + dil
        ids[k] = i
        xyz[k, 0], xyz[k, 1], xyz[k, 2] = x, y, z
        cov[k, 0], cov[k, 1], cov[k, 2], cov[k, 3] = a, b, c, a * c - b * b
        m2d[k, 0], m2d[k, 1] = mx, my
        k += 1
    return k


@nb.njit(cache=True)
def _visible(ids, xyz, cov, m2d, radii, opacities, w, h, rec, depths):
    """Second pass: keep the splats with a finite, positive-definite footprint that reaches the image:
    their ids (in place, the first k), records (mx, my, conic a, b, c, radius, opacity) and depths;
    returns k."""
    sixteen, fifteen = _F(16.0), _F(15.0)
    gx, gy = (w + TILE - 1) // TILE, (h + TILE - 1) // TILE
    k = 0
    for i in range(ids.shape[0]):
        a, b, c, det = cov[i, 0], cov[i, 1], cov[i, 2], cov[i, 3]
        mx, my, r = m2d[i, 0], m2d[i, 1], radii[i]
        if not (det > 0 and np.isfinite(det) and np.isfinite(r) and np.isfinite(mx) and np.isfinite(my)
                and np.isfinite(a) and np.isfinite(b) and np.isfinite(c)):
            continue
        box = (np.ceil(mx - r) <= np.floor(mx + r) and np.floor(mx + r) >= 0 and np.ceil(mx - r) <= w - 1
               and np.ceil(my - r) <= np.floor(my + r) and np.floor(my + r) >= 0 and np.ceil(my - r) <= h - 1)
        if not box:
            x0 = min(max(np.floor((mx - r) / sixteen), 0), gx)
            x1 = min(max(np.floor(((mx + r) + fifteen) / sixteen), 0), gx)
            y0 = min(max(np.floor((my - r) / sixteen), 0), gy)
            y1 = min(max(np.floor(((my + r) + fifteen) / sixteen), 0), gy)
            if not (x1 > x0 and y1 > y0):
                continue
        ids[k] = ids[i]
        rec[k, 0], rec[k, 1], rec[k, 2], rec[k, 3], rec[k, 4] = mx, my, c / det, -b / det, a / det
        rec[k, 5], rec[k, 6] = r, opacities[ids[i]]
        depths[k] = xyz[i, 2]
        k += 1
    return k


class Geometry:
    """A scene's parameters as contiguous float32 arrays, converted once for many views: centres,
    M = R·diag(exp ŝ) (Σ = M Mᵀ) and the opacities sigmoid(logit), the last two computed by torch as
    :func:`~renderers.projection.project_gaussians` computes them (each element's value depends on it
    alone), so the projection below matches it bit for bit."""

    def __init__(self, scene):
        f32 = lambda a: np.ascontiguousarray(a, dtype=np.float32)
        self.means = f32(scene.means)
        with torch.no_grad():
            scales = torch.exp(torch.from_numpy(f32(scene.scales_log)))
            self.m = (quats_to_rotmats(torch.from_numpy(f32(scene.quats))) * scales[:, None, :]).numpy()
            self.smax = scales.max(dim=1).values.numpy()
            self.opacities = sigmoid(torch.from_numpy(f32(scene.opacity_logit).reshape(-1))).numpy()

    def __len__(self) -> int:
        return int(self.means.shape[0])


def _radii(cov: np.ndarray) -> np.ndarray:
    """ceil(3·√λ_max) of each 2D covariance (a, b, c, det), in torch: its float32 sqrt is not always
    numpy's correctly rounded one (measured 1 ulp apart), and the radius is what the reference uses."""
    a, c, det = (torch.from_numpy(np.ascontiguousarray(cov[:, k])) for k in (0, 2, 3))
    mid = 0.5 * (a + c)
    return torch.ceil(3.0 * torch.sqrt(mid + torch.sqrt(torch.clamp_min(mid * mid - det, 0.1)))).numpy()


def project(geom: Geometry, camera: Camera) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(ids, records, depths) of the splats of ``geom`` visible in ``camera``, in scene order; a record
    is (means2d x, y, conic a, b, c, radius, opacity) as :class:`~renderers.projection.Projected`
    holds them (module docstring)."""
    n = len(geom)
    w, h = int(camera.width), int(camera.height)
    fx, fy, cx, cy = float(camera.fx), float(camera.fy), float(camera.cx), float(camera.cy)
    w2c = np.asarray(camera.world_to_cam, np.float32)
    tan_x, tan_y = 0.5 * w / fx, 0.5 * h / fy
    lims = np.array([-(cx / fx + 0.3 * tan_x), (w - cx) / fx + 0.3 * tan_x,
                     -(cy / fy + 0.3 * tan_y), (h - cy) / fy + 0.3 * tan_y], np.float32)
    ids, xyz = np.empty(n, np.int64), np.empty((n, 3), np.float32)
    cov, m2d = np.empty((n, 4), np.float32), np.empty((n, 2), np.float32)
    k = _front(geom.means, geom.m, geom.smax, np.ascontiguousarray(w2c[:3, :3]), np.ascontiguousarray(w2c[:3, 3]),
               _F(fx), _F(fy), _F(cx), _F(cy), lims, w, h, ids, xyz, cov, m2d)
    ids, xyz, cov, m2d = ids[:k], xyz[:k], cov[:k], m2d[:k]
    rec, depths = np.empty((k, RECORD), np.float32), np.empty(k, np.float32)
    k = _visible(ids, xyz, cov, m2d, _radii(cov), geom.opacities, w, h, rec, depths)
    return ids[:k], rec[:k], depths[:k]


@nb.njit(cache=True)
def _sweep(rec, w, h, early_stop, out):
    """Σ o·T of each splat of ``rec`` into ``out`` (module docstring); ``rec`` rows (mx, my, conic a,
    b, c, radius, opacity), front to back (one contiguous record each: the sweep reads them in order).
    ``trans`` holds each pixel's T, −1 once it has stopped; ``live`` the pixels of each row segment
    that have not."""
    amax, amin = _F(ALPHA_MAX), _F(ALPHA_MIN)
    trans = np.ones(w * h, np.float64)
    nseg = (w + SEGMENT - 1) // SEGMENT
    live = np.empty(h * nseg, np.int64)
    for yy in range(h):
        for s in range(nseg):
            live[yy * nseg + s] = min(SEGMENT, w - s * SEGMENT)
    for j in range(rec.shape[0]):
        mx, my, ca, cb, cc, r, o = rec[j, 0], rec[j, 1], rec[j, 2], rec[j, 3], rec[j, 4], rec[j, 5], rec[j, 6]
        a64, b64, c64 = np.float64(ca), np.float64(cb), np.float64(cc)
        k2 = max(2.0 * math.log(255.0 * max(np.float64(o), 1e-30)), 0.0)
        if k2 <= 0.0:
            continue
        det = max(a64 * c64 - b64 * b64, 1e-30)
        r64 = np.float64(r)
        hx = min(math.sqrt(k2 * c64 / det) + 1e-3, r64 + 1e-3)
        hy = min(math.sqrt(k2 * a64 / det) + 1e-3, r64 + 1e-3)
        x0, x1 = int(max(math.ceil(mx - hx), 0.0)), int(min(math.floor(mx + hx), w - 1.0))
        y0, y1 = int(max(math.ceil(my - hy), 0.0)), int(min(math.floor(my + hy), h - 1.0))
        # |x − mx| ≤ r in float32 holds on an interval of columns (the subtraction is monotone)
        while x0 <= x1 and abs(_F(x0) - mx) > r:
            x0 += 1
        while x1 >= x0 and abs(_F(x1) - mx) > r:
            x1 -= 1
        acc = 0.0
        for yy in range(y0, y1 + 1):
            dy = _F(yy) - my
            if abs(dy) > r:
                continue
            # the row's pixels that can pass the α test, q = a dx² + 2b dx dy + c dy² ≤ k2, with k2 loosened
            # by a bound on float32's error in q (the float32 test below decides)
            fdy = yy - np.float64(my)
            k2r = k2 + Q_SLACK * (a64 * hx * hx + c64 * fdy * fdy + 2.0 * abs(b64 * fdy) * hx + 1.0 + k2)
            disc = b64 * b64 * fdy * fdy - a64 * (c64 * fdy * fdy - k2r)
            if disc < 0.0:
                continue
            root = math.sqrt(disc)
            lo = np.float64(mx) + (-b64 * fdy - root) / a64 - 1e-3
            hi = np.float64(mx) + (-b64 * fdy + root) / a64 + 1e-3
            xx = max(x0, int(max(math.ceil(lo), -1.0)))
            xe = min(x1, int(min(math.floor(hi), w + 0.0)))
            row = yy * w
            while xx <= xe:
                last = min(xe, (xx // SEGMENT + 1) * SEGMENT - 1)
                seg = yy * nseg + xx // SEGMENT
                if live[seg] > 0:
                    for x in range(xx, last + 1):
                        t = trans[row + x]
                        if t < 0.0:
                            continue
                        dx = _F(x) - mx
                        power = _F(-0.5) * (ca * dx * dx + cc * dy * dy) - cb * dx * dy
                        if power > _F(0.0):
                            continue
                        alpha = min(amax, o * np.exp(power))
                        if alpha < amin:
                            continue
                        t_next = t * (1.0 - alpha)
                        if early_stop and t_next < T_EARLY_STOP:
                            trans[row + x] = -1.0
                            live[seg] -= 1
                            continue
                        acc += o * t
                        trans[row + x] = t_next
                xx = last + 1
        out[j] = acc


@nb.njit(cache=True)
def depth_order(depths):
    """Stable argsort of positive float32 depths (ties by index), as ``np.argsort(kind="stable")``: an
    LSD radix sort of their bit patterns (monotone for positive floats), 11 bits a pass."""
    keys = depths.view(np.uint32).copy()
    n = keys.shape[0]
    order = np.arange(n)
    keys2, order2 = np.empty_like(keys), np.empty(n, np.int64)
    for shift in (0, 11, 22):
        count = np.zeros(2049, np.int64)
        for i in range(n):
            count[((keys[i] >> shift) & 2047) + 1] += 1
        for b in range(2048):
            count[b + 1] += count[b]
        for i in range(n):
            d = (keys[i] >> shift) & 2047
            keys2[count[d]] = keys[i]
            order2[count[d]] = order[i]
            count[d] += 1
        keys, keys2, order, order2 = keys2, keys, order2, order
    return order


@nb.njit(cache=True)
def _gather(rec, order):
    out = np.empty_like(rec)
    for i in range(order.shape[0]):
        out[i] = rec[order[i]]
    return out


def opacity_transmittance(geom: Geometry, camera: Camera, *, early_stop: bool = True) -> tuple:
    """(ids, Σ_pixels o·T per visible splat (float64)) of one view (module docstring)."""
    ids, rec, depths = project(geom, camera)
    order = depth_order(depths)
    rec = _gather(rec, order)
    sums = np.zeros(len(ids), np.float64)
    _sweep(rec, int(camera.width), int(camera.height), early_stop, sums)
    out = np.empty(len(ids), np.float64)
    out[order] = sums
    return ids, out
