"""Project 3D Gaussians to screen-space splats with the classic 3DGS math (graphdeco / gsplat "classic").

For a splat with centre μ, log-scales ŝ, quaternion q (w, x, y, z) and a camera with world-to-camera
rotation W, translation t, focal lengths fx, fy, principal point cx, cy and size w × h:

* view point p = W μ + t (OpenCV axes: x right, y down, z forward); **cull z ≤ 0.2** (strict ``z > 0.2``
  kept, as graphdeco ``in_frustum``).
* Σ = R S Sᵀ Rᵀ with S = diag(exp ŝ) and R from q normalised on use; a zero-norm quaternion is read as
  the identity rotation (as :func:`harness.core.scene.normalized_quats`).
* EWA: J = [[fx/z, 0, −fx·x'/z²], [0, fy/z, −fy·y'/z²]] at x' = clamp(x/z, −lim_x⁻, lim_x⁺)·z (same
  for y) with gsplat's limits lim_x⁺ = (w − cx)/fx + 0.3·tan_x, lim_x⁻ = cx/fx + 0.3·tan_x,
  tan_x = w / (2 fx). For a centred principal point (cx = w/2) this is graphdeco's ±1.3·tan(fov_x/2);
  graphdeco ignores cx altogether, gsplat's form is the natural generalisation.
* cov2d = J W Σ Wᵀ Jᵀ + 0.3·I (the low-pass dilation); det = a·c − b²; splats with det ≤ 0 or any
  non-finite value are dropped (overflowing scales, NaN input).
* conic = cov2d⁻¹ = (c, −b, a)/det; λ_max = mid + √max(0.1, mid² − det), mid = (a + c)/2;
  **radius = ceil(3·√λ_max)** pixels (kept as float32 so huge splats cannot overflow an int).
* **Pixel convention** (graphdeco ``ndc2Pix``): means2d = (fx·x/z + cx − 0.5, fy·y/z + cy − 0.5). The
  centre of pixel (column i, row j) is the point (i, j) of this frame, i.e. the usual pixel-area
  convention (pixel i covers [i, i+1) in ``u = fx·x/z + cx``) shifted by half a pixel. Both renderers
  evaluate the Gaussian at d = (i, j) − means2d.
* colour = max(SH(dir) + 0.5, 0) with dir = normalise(μ − camera centre) (:mod:`renderers.sh`);
  opacity = sigmoid(logit) (:func:`sigmoid`) unless activated opacities are given.

**Each splat's values depend on that splat alone**, not on where it sits among the others, so the
splats of a pruned scene project to exactly (bit for bit) their values in the full scene: a renderer
may project a view once and filter it per keep mask (:meth:`renderers.gl.PackedView.kept`). Every
operation here is elementwise or a per-splat product of 3×3 matrices except torch's CPU sigmoid,
which is made so by :func:`sigmoid`; ``tests/test_view_filter.py`` checks the property on real and
generated scenes.

Image-overlap cull: a splat is kept when its ±radius box contains a pixel centre, or graphdeco's tile
rectangle (``getRect``, 16-px tiles) is non-empty — the union, so that either footprint convention of
:mod:`renderers.reference` (and the GL quads covering ±radius) sees every splat it could draw.

Gradients flow (plain torch autograd) from ``means2d``, ``conics``, ``colors`` and ``opacities`` back to the
tensors of a :class:`SplatTensors` that require grad; the visibility decisions are not differentiated.

**Two array libraries, one projection** (:mod:`renderers.arrays`): :func:`project_gaussians` runs on
torch (a device, autograd: the reference renderer and the camera-aware pruners), :func:`project_arrays`
on numpy (the GL renderer on the CPU, without importing torch); the code below is the same for both.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from harness.core.cameras import Camera
from harness.core.scene import GaussianScene
from renderers.arrays import ops_for
from renderers.sh import sh_to_color

NEAR_Z = 0.2
DILATION = 0.3
TILE = 16


def default_device(device=None):
    """``device`` if given, else CUDA when available, else the CPU (a torch device)."""
    import torch

    if device is not None:
        return torch.device(device)
    return torch.device("cuda" if torch.cuda.is_available() else "cpu")


@dataclass
class SplatTensors:
    """A scene's stored parameters as arrays of one library: torch tensors on one device (any float
    dtype; may require grad), or float32 numpy arrays (:meth:`arrays`).

    ``sh`` is (N, K+1, 3): dc first, then the higher coefficients coefficient-major.
    """

    means: object
    scales_log: object
    quats: object
    opacity_logit: object
    sh: object

    @classmethod
    def from_scene(cls, scene: GaussianScene, device=None, dtype=None) -> SplatTensors:
        """torch tensors of ``dtype`` (default float32) on ``device`` (:func:`default_device`)."""
        import torch

        dev, dtype = default_device(device), dtype or torch.float32
        t = lambda a: torch.as_tensor(np.ascontiguousarray(a), dtype=dtype, device=dev)
        sh = np.concatenate([scene.sh_dc[:, None, :], scene.sh_rest], axis=1)
        return cls(t(scene.means), t(scene.scales_log), t(scene.quats), t(scene.opacity_logit), t(sh))

    @classmethod
    def arrays(cls, scene: GaussianScene) -> SplatTensors:
        """float32 numpy arrays (the CPU projection of the GL renderer)."""
        t = lambda a: np.ascontiguousarray(a, dtype=np.float32)
        sh = np.concatenate([scene.sh_dc[:, None, :], scene.sh_rest], axis=1)
        return cls(t(scene.means), t(scene.scales_log), t(scene.quats), t(scene.opacity_logit), t(sh))

    def __len__(self) -> int:
        return int(self.means.shape[0])

    @property
    def sh_degree(self) -> int:
        return {1: 0, 4: 1, 9: 2, 16: 3}[int(self.sh.shape[1])]

    @property
    def device(self):
        return self.means.device

    @property
    def dtype(self):
        return self.means.dtype


@dataclass
class Projected:
    """Visible splats only (M of the scene's N), arrays of one library (on one device).

    ids (M,) int64 index into the scene · means2d (M, 2) pixel coordinates (x right, y down; pixel
    centres at integers, see the module docstring) · conics (M, 3) (a, b, c) of [[a, b], [b, c]] =
    cov2d⁻¹ · depths (M,) view-space z · radii (M,) float, ceil(3√λ_max) · colors (M, 3) SH colour +
    0.5 clamped at 0 · opacities (M,) activated. ``width``/``height`` are the image size it was
    projected for.
    """

    ids: object
    means2d: object
    conics: object
    depths: object
    radii: object
    colors: object
    opacities: object
    width: int
    height: int

    def __len__(self) -> int:
        return int(self.ids.shape[0])


def sigmoid(x):
    """σ(x) = 1 / (1 + e^(−x)) from elementwise operations: each element's value depends on it alone.

    torch.sigmoid's CPU kernel computes the last ``n mod 2·lanes`` elements of each parallel chunk
    with a scalar formula that differs in the last bit from its vectorised one for about 1 input in
    15 (measured, AVX-512), so a splat's opacity would depend on how many splats precede it.
    """
    return 1.0 / (1.0 + ops_for(x).lib.exp(-x))


def rowwise_matmul(a, b):
    """``a @ b`` for small matrices (broadcast stacks ``(..., r, k) @ (..., k, c)``), entry by entry:
    ``(a₀b₀ + a₁b₁) + a₂b₂ …`` from elementwise products and sums in that order.

    One splat's result then depends on its own matrices alone. torch's matmul picks its kernel by
    the stack's size (BLAS with fused multiply-adds for some, a plain loop for others), so the same
    splat rounded differently alone than among thousands (numpy's matmul likewise).
    """
    out = a[..., :, 0:1] * b[..., 0:1, :]
    for k in range(1, a.shape[-1]):
        out = out + a[..., :, k:k + 1] * b[..., k:k + 1, :]
    return out


def row_norms(v):
    """Euclidean norms of the rows of ``v`` (..., d), keepdim: ``√((v₀² + v₁²) + …)`` in that order."""
    sq = v[..., 0:1] * v[..., 0:1]
    for k in range(1, v.shape[-1]):
        sq = sq + v[..., k:k + 1] * v[..., k:k + 1]
    return ops_for(v).lib.sqrt(sq)


def quats_to_rotmats(quats):
    """(N, 3, 3) rotation matrices from (w, x, y, z) quaternions normalised on use; zero norm → identity."""
    xp = ops_for(quats).lib
    norm = row_norms(quats)
    ident = xp.zeros_like(quats)
    ident[:, 0] = 1.0
    q = xp.where(norm > 0, quats / xp.where(norm > 0, norm, xp.ones_like(norm)), ident)
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    rows = [
        xp.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        xp.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        xp.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ]
    return xp.stack(rows, -2)


def tile_rects(means2d, radii, width: int, height: int):
    """graphdeco ``getRect``: tile ranges [x0, x1) × [y0, y1) touched by the ±radius box (16-px tiles).

    x0 = clamp(⌊(x − r)/16⌋, 0, gx), x1 = clamp(⌊(x + r + 15)/16⌋, 0, gx) (C's int truncation equals the
    floor wherever the clamp does not apply). Returns four int64 arrays.
    """
    ops = ops_for(means2d)
    xp = ops.lib
    gx, gy = (width + TILE - 1) // TILE, (height + TILE - 1) // TILE
    x, y = ops.detach(means2d[:, 0]), ops.detach(means2d[:, 1])
    r = ops.detach(radii)

    def rng(lo, hi, g):
        a = ops.as_index(xp.clip(xp.floor(lo / TILE), 0, g))
        b = ops.as_index(xp.clip(xp.floor((hi + TILE - 1) / TILE), 0, g))
        return a, b

    x0, x1 = rng(x - r, x + r, gx)
    y0, y1 = rng(y - r, y + r, gy)
    return x0, x1, y0, y1


def project_gaussians(scene_or_tensors, camera: Camera, *, device=None, opacities=None) -> Projected:
    """Project a :class:`GaussianScene` (uploaded as float32 torch tensors on ``device``) or
    :class:`SplatTensors` (used as they are, their library, device and dtype win) for ``camera``;
    ``opacities`` (N,) overrides sigmoid(opacity_logit) and may require grad. Returns the visible
    splats in scene order (not depth-sorted)."""
    if isinstance(scene_or_tensors, SplatTensors):
        st = scene_or_tensors
    else:
        st = SplatTensors.from_scene(scene_or_tensors, device=device)
    return _project(st, camera, opacities)


def project_arrays(scene: GaussianScene, camera: Camera) -> Projected:
    """:func:`project_gaussians` on float32 numpy arrays (no torch): the GL renderer's CPU path."""
    return _project(SplatTensors.arrays(scene), camera, None)


def _camera_arrays(camera: Camera, ops, like):
    """(rotation, translation, centre) of ``camera`` in the library, dtype and device of ``like``."""
    w2c = ops.asarray(camera.world_to_cam, like.dtype, like)
    centre = ops.asarray(camera.center, like.dtype, like)
    return w2c[:3, :3], w2c[:3, 3], centre


def _project(st: SplatTensors, camera: Camera, opacities) -> Projected:
    """The projection (module docstring) in the library of ``st``'s arrays."""
    ops = ops_for(st.means)
    xp = ops.lib
    w, h = int(camera.width), int(camera.height)
    fx, fy, cx, cy = float(camera.fx), float(camera.fy), float(camera.cx), float(camera.cy)
    rot, trans, centre = _camera_arrays(camera, ops, st.means)

    # near cull first (cheap), on detached values; z is the same sum as p's below
    with ops.no_grad():
        means_d = ops.detach(st.means)
        z_all = (means_d[:, 0] * rot[2, 0] + means_d[:, 1] * rot[2, 1]) + means_d[:, 2] * rot[2, 2] + trans[2]
        ids = ops.flatnonzero(z_all > NEAR_Z)
    means = st.means[ids]
    p = rowwise_matmul(means[:, None, :], rot.T)[:, 0] + trans
    x, y, z = p[:, 0], p[:, 1], p[:, 2]

    # Σ = R S Sᵀ Rᵀ = m mᵀ with m = R S (per splat)
    m = quats_to_rotmats(st.quats[ids]) * xp.exp(st.scales_log[ids])[:, None, :]

    tan_x, tan_y = 0.5 * w / fx, 0.5 * h / fy
    lim_xp, lim_xn = (w - cx) / fx + 0.3 * tan_x, cx / fx + 0.3 * tan_x
    lim_yp, lim_yn = (h - cy) / fy + 0.3 * tan_y, cy / fy + 0.3 * tan_y
    tx = xp.clip(x / z, -lim_xn, lim_xp) * z
    ty = xp.clip(y / z, -lim_yn, lim_yp) * z
    zero = xp.zeros_like(z)
    jac = xp.stack(
        [
            xp.stack([fx / z, zero, -fx * tx / (z * z)], -1),
            xp.stack([zero, fy / z, -fy * ty / (z * z)], -1),
        ],
        -2,
    )  # (M, 2, 3)
    # cov2d = J W Σ Wᵀ Jᵀ = T Tᵀ with T = J W m (2 × 3 per splat)
    t = rowwise_matmul(rowwise_matmul(jac, rot), m)
    cov2d = rowwise_matmul(t, t.swapaxes(1, 2))
    a = cov2d[:, 0, 0] + DILATION
    b = cov2d[:, 0, 1]
    c = cov2d[:, 1, 1] + DILATION
    det = a * c - b * b
    means2d = xp.stack([fx * x / z + cx - 0.5, fy * y / z + cy - 0.5], -1)

    with ops.no_grad():
        mid = 0.5 * (a + c)
        lam = mid + xp.sqrt(xp.clip(mid * mid - det, 0.1, None))
        radii = xp.ceil(3.0 * xp.sqrt(lam))
        ok = (det > 0) & xp.isfinite(det) & xp.isfinite(radii) & xp.isfinite(means2d).all(-1)
        ok &= xp.isfinite(a) & xp.isfinite(b) & xp.isfinite(c)
        mx, my = ops.detach(means2d[:, 0]), ops.detach(means2d[:, 1])
        radii = ops.detach(radii)
        # ±r box contains a pixel centre (integers 0..w-1, 0..h-1) ...
        box_hit = (xp.ceil(mx - radii) <= xp.floor(mx + radii)) & (xp.floor(mx + radii) >= 0)
        box_hit &= xp.ceil(mx - radii) <= w - 1
        box_hit &= (xp.ceil(my - radii) <= xp.floor(my + radii)) & (xp.floor(my + radii) >= 0)
        box_hit &= xp.ceil(my - radii) <= h - 1
        # ... or graphdeco's tile rectangle is non-empty
        x0, x1, y0, y1 = tile_rects(means2d, radii, w, h)
        ok &= box_hit | ((x1 > x0) & (y1 > y0))
        keep = ops.flatnonzero(ok)

    ids = ids[keep]
    det_k = det[keep]
    conics = xp.stack([c[keep] / det_k, -b[keep] / det_k, a[keep] / det_k], -1)
    dirs = means[keep] - centre
    dirs = dirs / row_norms(dirs)
    colors = sh_to_color(st.sh[ids], dirs, st.sh_degree)
    if opacities is None:
        opac = sigmoid(st.opacity_logit[ids])
    else:
        opac = ops.asarray(opacities, st.dtype, st.means).reshape(-1)[ids]
    return Projected(
        ids=ids,
        means2d=means2d[keep],
        conics=conics,
        depths=z[keep],
        radii=ops.cast(radii[keep], st.dtype),
        colors=colors,
        opacities=opac,
        width=w,
        height=h,
    )
