"""Robust placement statistics of a splat scene, for putting synthetic cameras around it.

Trained scenes carry far floaters and faint background splats, so nothing here uses the raw
bounding box. Statistics are computed on a sample of splat centres drawn with probability ∝ opacity
(so a plain percentile of the sample is an opacity-weighted percentile of the scene); the sample
is fixed (``numpy`` generator seeded with 0) so the statistics are a deterministic function of
the scene alone.

* ``center``: per-axis median of the sample (the opacity-weighted median of the centres).
* ``points``: the sample without floaters: centres within the 95th percentile of the distance to
  ``center``. ``radius``: the 90th percentile of that distance.
* ``dense_center``: the peak of the opacity-weighted density (3-D histogram of 24³ cells over the
  ``points`` box, Gaussian-smoothed with σ = 1 cell, then three mean-shift steps with a 2-cell
  window). In a captured room this is the detailed object the capture circled (bonsai); in an
  object scene it lies on the object.
* ``up``: the world direction drawn upwards in images. Not derivable from splats reliably, so it is
  given (per-scene table in :mod:`harness.views.rigs`) or defaults to −y, the usual orientation of
  COLMAP-derived 3DGS scenes (the capture camera's y axis points down).
* :func:`enclosure`: the fraction of view directions, from points between ``dense_center`` and the
  content's edge, in which content is seen. Measured: bonsai-7k (a room) 0.62; playbot (object on a
  ground plane) 0.42; luigi, grape-small, bonsai-7k-mini (objects) 0.24–0.29.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from harness.core.correlate import correlate_symmetric
from harness.core.scene import GaussianScene, opacities
from harness.core.sphere import fibonacci_sphere

DEFAULT_UP = (0.0, -1.0, 0.0)
SAMPLE_SIZE = 20000


@dataclass(frozen=True)
class Placement:
    center: np.ndarray  # (3,)
    dense_center: np.ndarray  # (3,)
    up: np.ndarray  # (3,) unit
    radius: float
    points: np.ndarray  # (M, 3) float64, floaters removed

    @property
    def horizontal_basis(self) -> tuple[np.ndarray, np.ndarray]:
        """Two unit vectors spanning the plane perpendicular to ``up`` (right-handed with it)."""
        helper = np.array([1.0, 0.0, 0.0]) if abs(self.up[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
        e1 = np.cross(self.up, helper)
        e1 /= np.linalg.norm(e1)
        return e1, np.cross(self.up, e1)

    def direction(self, azimuth: float, elevation: float) -> np.ndarray:
        """Unit vector at ``azimuth`` around ``up`` and ``elevation`` above the horizontal (radians)."""
        e1, e2 = self.horizontal_basis
        return np.cos(elevation) * (np.cos(azimuth) * e1 + np.sin(azimuth) * e2) + np.sin(elevation) * self.up


def _sample(scene: GaussianScene, size: int) -> np.ndarray:
    means = scene.means.astype(np.float64)
    finite = np.all(np.isfinite(means), axis=1)
    w = opacities(scene).astype(np.float64) * finite
    if w.sum() <= 0:
        w = finite.astype(np.float64)
    if w.sum() <= 0:
        raise ValueError("the scene has no finite splat centre to place cameras around")
    rng = np.random.default_rng(0)
    idx = rng.choice(len(means), size=size, replace=True, p=w / w.sum())
    return means[idx]


def gaussian_blur(volume: np.ndarray, sigma: float = 1.0, truncate: float = 4.0) -> np.ndarray:
    """``scipy.ndimage.gaussian_filter(volume, sigma, mode="constant")`` bit for bit, without
    importing scipy.ndimage (0.3 s of every ``harness render``): along each axis in turn, the
    normalised kernel w_k ∝ exp(−k²/2σ²), |k| ≤ r = ⌊truncate·σ + ½⌋, applied as scipy's symmetric
    loop does (:func:`harness.core.correlate.correlate_symmetric`) with zeros beyond the edges."""
    r = int(truncate * sigma + 0.5)
    k = np.arange(-r, r + 1)
    w = np.exp(-0.5 / (sigma * sigma) * k ** 2)
    w = w / w.sum()
    out = np.asarray(volume, np.float64)
    for axis in range(out.ndim):
        out = correlate_symmetric(out, w, axis)
    return np.ascontiguousarray(out)


def _density_peak(points: np.ndarray, bins: int = 24) -> np.ndarray:
    lo, hi = points.min(0), points.max(0)
    span = np.maximum(hi - lo, 1e-9)
    hist, edges = np.histogramdd(points, bins=bins, range=list(zip(lo, lo + span)))
    hist = gaussian_blur(hist, sigma=1.0)
    cell = np.unravel_index(np.argmax(hist), hist.shape)
    peak = np.array([(edges[d][cell[d]] + edges[d][cell[d] + 1]) / 2 for d in range(3)])
    window = 2.0 * float(np.linalg.norm(span / bins))
    for _ in range(3):  # mean shift within the window
        near = points[np.linalg.norm(points - peak, axis=1) <= window]
        if len(near) == 0:
            break
        peak = near.mean(0)
    return peak


def placement(scene: GaussianScene, up=None, sample_size: int = SAMPLE_SIZE) -> Placement:
    """Robust statistics of ``scene`` (see the module docstring); ``up`` defaults to −y."""
    if len(scene) == 0:
        raise ValueError("cannot place cameras around an empty scene")
    pts = _sample(scene, sample_size)
    center = np.median(pts, axis=0)
    dist = np.linalg.norm(pts - center, axis=1)
    points = pts[dist <= np.percentile(dist, 95)]
    radius = float(np.percentile(dist, 90))
    up = np.asarray(DEFAULT_UP if up is None else up, np.float64)
    if not np.all(np.isfinite(up)) or np.linalg.norm(up) == 0:
        raise ValueError("up must be a finite non-zero vector")
    return Placement(center, _density_peak(points), up / np.linalg.norm(up), max(radius, 1e-6), points)


def enclosure(place: Placement, n_dirs: int = 64, eye_fraction: float = 0.3, share: float = 0.05) -> float:
    """Mean over four eyes (azimuths 0°, 90°, 180°, 270°, elevation 20°, at ``eye_fraction`` of the
    90th-percentile content distance from ``dense_center``) of the fraction of ``n_dirs`` direction
    cells (nearest of a Fibonacci sphere) holding at least ``share`` of a uniform share of the points."""
    dirs = fibonacci_sphere(n_dirs)
    d_edge = np.percentile(np.linalg.norm(place.points - place.dense_center, axis=1), 90)
    fractions = []
    for az in np.arange(4) * np.pi / 2:
        eye = place.dense_center + eye_fraction * d_edge * place.direction(az, np.radians(20.0))
        v = place.points - eye
        v = v[np.linalg.norm(v, axis=1) > 1e-9]
        v /= np.linalg.norm(v, axis=1, keepdims=True)
        cells = np.bincount(np.argmax(v @ dirs.T, axis=1), minlength=n_dirs)
        fractions.append(np.mean(cells >= share * len(v) / n_dirs))
    return float(np.mean(fractions))
