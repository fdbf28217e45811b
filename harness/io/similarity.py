"""Similarity transforms between a capture's frame and a splat file's frame.

A similarity maps points as ``x' = s·R·x + t`` (R a proper rotation, s > 0) and cameras as
rigid bodies riding along: the centre moves like a point, ``C' = s·R·C + t``, and the
camera-to-world rotation turns with the frame, ``rotation' = R·rotation`` (the scale changes
distances, never angles, so intrinsics stay). In world-to-camera form
``R_w2c' = R_w2c·Rᵀ`` and ``t' = −R_w2c'·C'``.

A chain ``[T1, T2, ...]`` applies T1 first: ``T2∘T1 = (s2·s1, R2·R1, s2·R2·t1 + t2)``.

File form (``transform.json`` beside a capture, or a manifest entry): an object with ``R`` (3×3
numbers, rows), ``s`` and ``t`` (3 numbers); other keys (notes) are ignored. ``R`` must be
orthonormal to :data:`ORTHO_TOL` with determinant +1 — a shear, a non-uniform scale or a
reflection is not a similarity and is refused — and is then re-orthonormalised by SVD.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from harness.core.cameras import Camera, is_real
from harness.core.errors import InputError

#: largest |RᵀR − I| entry accepted (fitted rotations are stored to ~1e-16)
ORTHO_TOL = 1e-6


@dataclass(frozen=True)
class Similarity:
    R: np.ndarray
    s: float
    t: np.ndarray

    @classmethod
    def identity(cls) -> Similarity:
        return cls(np.eye(3), 1.0, np.zeros(3))

    def points(self, x) -> np.ndarray:
        """``s·R·x + t`` for points ``x`` of shape (..., 3)."""
        return self.s * np.asarray(x, np.float64) @ self.R.T + self.t

    def then(self, other: Similarity) -> Similarity:
        """``other ∘ self``: this transform first, then ``other``."""
        return Similarity(other.R @ self.R, other.s * self.s, other.s * other.R @ self.t + other.t)

    def camera(self, cam: Camera) -> Camera:
        """The camera moved into the new frame (module docstring)."""
        from dataclasses import replace

        r_w2c = cam.rotation @ self.R.T
        center = self.points(cam.center)
        m = np.eye(4)
        m[:3, :3] = r_w2c
        m[:3, 3] = -r_w2c @ center
        return replace(cam, world_to_cam=m)


def similarity_problem(d) -> str | None:
    """Why a parsed object is not a similarity ``{R, s, t}``, or None."""
    if not isinstance(d, dict):
        return "expected an object with R (3x3), s and t (3 numbers)"
    missing = [k for k in ("R", "s", "t") if k not in d]
    if missing:
        return f"lacks {', '.join(missing)} (a similarity is x' = s*R*x + t)"
    r, s, t = d["R"], d["s"], d["t"]
    if not (isinstance(r, list) and len(r) == 3 and all(isinstance(row, list) and len(row) == 3
                                                         and all(is_real(v) for v in row) for row in r)):
        return "R must be 3 rows of 3 numbers"
    if not (isinstance(t, list) and len(t) == 3 and all(is_real(v) for v in t)):
        return "t must be 3 numbers"
    if not is_real(s) or not np.isfinite(float(s)) or float(s) <= 0:
        return f"s must be a positive number, got {s!r}"
    R = np.asarray(r, np.float64)
    if not (np.all(np.isfinite(R)) and np.all(np.isfinite(np.asarray(t, np.float64)))):
        return "R and t must be finite"
    err = float(np.abs(R.T @ R - np.eye(3)).max())
    if err > ORTHO_TOL:
        return (f"R is not a rotation (|RᵀR − I| reaches {err:.3g}; a shear or non-uniform scale is not a "
                "similarity: put the uniform scale in s)")
    if np.linalg.det(R) < 0:
        return "R is a reflection (determinant −1), not a rotation: a similarity keeps handedness"
    return None


def parse_similarity(d, source) -> Similarity:
    """A :class:`Similarity` from ``{R, s, t}``; anything else is an :class:`InputError`."""
    why = similarity_problem(d)
    if why:
        raise InputError(source, f"transform is not a similarity: {why}")
    u, _, vt = np.linalg.svd(np.asarray(d["R"], np.float64))
    return Similarity(u @ vt, float(d["s"]), np.asarray(d["t"], np.float64))


def parse_chain(value, source) -> Similarity:
    """One similarity, or a list of them applied in order, composed into one."""
    items = value if isinstance(value, list) else [value]
    if not items:
        raise InputError(source, "transform is not a similarity: an empty list")
    out = Similarity.identity()
    for i, d in enumerate(items):
        why = similarity_problem(d)
        if why:
            where = f" (entry {i})" if isinstance(value, list) else ""
            raise InputError(source, f"transform is not a similarity{where}: {why}")
        out = out.then(parse_similarity(d, source))
    return out
