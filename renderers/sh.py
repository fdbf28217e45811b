"""Real spherical harmonics up to degree 3, exactly as the classic 3DGS rasterizer evaluates them.

``eval_sh(sh, dirs, degree)`` returns Σ_k c_k · Y_k(dir) for every splat, with the constants and sign
conventions of graphdeco-inria ``computeColorFromSH`` (the same as gsplat's ``spherical_harmonics``):

* degree 0: ``C0·sh0``
* degree 1: ``− C1·y·sh1 + C1·z·sh2 − C1·x·sh3``
* degree 2: ``C2[0]·xy·sh4 + C2[1]·yz·sh5 + C2[2]·(2zz − xx − yy)·sh6 + C2[3]·xz·sh7 + C2[4]·(xx − yy)·sh8``
* degree 3: ``C3[0]·y(3xx − yy)·sh9 + C3[1]·xyz·sh10 + C3[2]·y(4zz − xx − yy)·sh11
  + C3[3]·z(2zz − 3xx − 3yy)·sh12 + C3[4]·x(4zz − xx − yy)·sh13 + C3[5]·z(xx − yy)·sh14
  + C3[6]·x(xx − 3yy)·sh15``

``dirs`` are unit vectors from the camera centre to the splat centre in *world* coordinates. The caller
adds 0.5 and clamps at 0 (:func:`sh_to_color`). Arrays are numpy or torch (:mod:`renderers.arrays`).
"""

from __future__ import annotations

from renderers.arrays import ops_for

SH_C0 = 0.28209479177387814
SH_C1 = 0.4886025119029199
SH_C2 = (1.0925484305920792, -1.0925484305920792, 0.31539156525252005, -1.0925484305920792,
         0.5462742152960396)
SH_C3 = (-0.5900435899266435, 2.890611442640554, -0.4570457994644658, 0.3731763325901154,
         -0.4570457994644658, 1.445305721320277, -0.5900435899266435)

#: number of coefficients per channel (dc included) for degrees 0..3
SH_COEFFS = {0: 1, 1: 4, 2: 9, 3: 16}


def sh_basis(dirs, degree: int):
    """The (M, (degree+1)²) basis values Y_k(dir) with the 3DGS signs and constants."""
    if degree not in SH_COEFFS:
        raise ValueError(f"SH degree must be 0..3, got {degree}")
    xp = ops_for(dirs).lib
    x, y, z = dirs[..., 0], dirs[..., 1], dirs[..., 2]
    cols = [xp.full_like(x, SH_C0)]
    if degree > 0:
        cols += [-SH_C1 * y, SH_C1 * z, -SH_C1 * x]
    if degree > 1:
        xx, yy, zz = x * x, y * y, z * z
        xy, yz, xz = x * y, y * z, x * z
        cols += [
            SH_C2[0] * xy,
            SH_C2[1] * yz,
            SH_C2[2] * (2.0 * zz - xx - yy),
            SH_C2[3] * xz,
            SH_C2[4] * (xx - yy),
        ]
        if degree > 2:
            cols += [
                SH_C3[0] * y * (3.0 * xx - yy),
                SH_C3[1] * xy * z,
                SH_C3[2] * y * (4.0 * zz - xx - yy),
                SH_C3[3] * z * (2.0 * zz - 3.0 * xx - 3.0 * yy),
                SH_C3[4] * x * (4.0 * zz - xx - yy),
                SH_C3[5] * z * (xx - yy),
                SH_C3[6] * x * (xx - 3.0 * yy),
            ]
    return xp.stack(cols, -1)


def eval_sh(sh, dirs, degree: int):
    """Σ_k sh[:, k, :]·Y_k(dirs) → (M, 3).

    ``sh`` is (M, K+1, 3): the dc coefficient first, then the higher ones coefficient-major (the
    :class:`harness.core.scene.GaussianScene` layout). Only the first (degree+1)² coefficients are used, so a
    scene may be evaluated at a lower degree than it stores; asking for more than it stores is an error.
    """
    n = SH_COEFFS.get(degree)
    if n is None:
        raise ValueError(f"SH degree must be 0..3, got {degree}")
    if sh.shape[1] < n:
        raise ValueError(f"degree {degree} needs {n} SH coefficients, got {sh.shape[1]}")
    basis = sh_basis(dirs, degree)  # (M, n)
    # summed in coefficient order from elementwise products: a splat's colour depends on its own
    # values alone (an einsum's kernel, and so its rounding, depends on how many splats there are)
    out = basis[:, 0:1] * sh[:, 0]
    for k in range(1, n):
        out = out + basis[:, k:k + 1] * sh[:, k]
    return out


def sh_to_color(sh, dirs, degree: int):
    """The 3DGS splat colour max(eval_sh + 0.5, 0), (M, 3)."""
    return ops_for(sh).lib.clip(eval_sh(sh, dirs, degree) + 0.5, 0.0, None)
