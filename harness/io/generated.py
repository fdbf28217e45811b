"""Scenes this project generates: splat models of simple geometry, seeded and bit-reproducible.

They stand in where no public trained scene of a kind could be had from the package registries: a
**room** (``synth-room``: floor, four walls, a sparse ceiling, a table with a vase and a plant on
it, a cabinet and a chair, seen from inside) and an **object standing on the ground**
(``synth-statue``: a figure on a pedestal on a grass-and-dirt ground patch). They are *not* trained
on photographs: every splat is placed on a known surface, so they lack a real capture's floaters,
view-dependent colour and densification pattern — they test where a camera-free method puts its
views, not how it copes with a real reconstruction. Statistics chosen to resemble trained scenes:
flat splats (normal axis 1/12 of the tangent ones) sized to tile their surface (log-normal, σ =
0.3), opacities from a mixture of 70 % opaque (logit N(3, 1)) and 30 % translucent (logit N(−0.5,
1.2)), colour as procedural value noise over a base colour, SH degree 0, and 1 % low-opacity
floaters. The whole scene is turned by a seeded random rotation, so no axis of the file's frame is
up (:func:`up_of` says where up went, for the harness's test rigs only).

Reproducible to the byte on any machine with the pinned numpy: only NumPy's seeded generator and
IEEE-exact arithmetic (+, −, ×, ÷, √, floor) are used — no sin, cos, exp or log, whose vectorised
forms may round differently on other CPUs — and the file's sha256 is pinned in
:mod:`harness.io.datasets`; ``harness fetch NAME`` writes it and checks that.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from harness.core.scene import GaussianScene, quat_to_rotmat

SH_C0 = 0.28209479177387814
SEEDS = {"synth-room": 101, "synth-statue": 202}


class _Builder:
    """Accumulates splats surface by surface (module docstring for the statistics)."""

    def __init__(self, seed: int):
        self.rotation = _turn(seed)
        self.rng = np.random.default_rng(seed)
        self.parts: list[tuple[np.ndarray, ...]] = []
        self.lattice = self.rng.uniform(0.0, 1.0, size=(17, 17, 17))

    def noise(self, p: np.ndarray, freq: float) -> np.ndarray:
        """Trilinear value noise in [0, 1] over a periodic 16³ lattice (arithmetic only)."""
        q = p * freq
        i = np.floor(q)
        f = q - i
        i = i.astype(np.int64) % 16
        out = np.zeros(len(p))
        for dx in (0, 1):
            for dy in (0, 1):
                for dz in (0, 1):
                    w = ((f[:, 0] if dx else 1 - f[:, 0]) * (f[:, 1] if dy else 1 - f[:, 1])
                         * (f[:, 2] if dz else 1 - f[:, 2]))
                    out += w * self.lattice[i[:, 0] + dx, i[:, 1] + dy, i[:, 2] + dz]
        return out

    def unit(self, n: int, dims: int = 3) -> np.ndarray:
        v = self.rng.normal(size=(n, dims))
        return v / np.sqrt((v * v).sum(1, keepdims=True))

    def add(self, points, normals, area: float, colour, freq: float = 3.0, contrast: float = 0.25) -> None:
        """Splats tangent to a surface at ``points`` with unit ``normals`` covering ``area``."""
        n = len(points)
        spacing = float(np.sqrt(area / n))
        tangent = spacing * (1.0 + 0.3 * self.rng.normal(size=(n, 2))).clip(0.3, 3.0)
        scales = np.concatenate([tangent, (tangent.min(1, keepdims=True) / 12.0)], axis=1)
        opaque = self.rng.uniform(size=n) < 0.7
        logits = np.where(opaque, self.rng.normal(3.0, 1.0, n), self.rng.normal(-0.5, 1.2, n))
        shade = self.noise(points, freq) - 0.5 + 0.5 * (self.noise(points, 4 * freq) - 0.5)
        rgb = np.clip(np.asarray(colour, np.float64) * (1.0 + contrast * 2.0 * shade)[:, None], 0.0, 1.0)
        self.parts.append((points, _quat_z_to(normals, self.unit(n, 2)), scales, logits, rgb))

    def floaters(self, n: int, lo, hi, size: float) -> None:
        pts = self.rng.uniform(lo, hi, size=(n, 3))
        scales = np.full((n, 3), size) * (1.0 + 0.3 * self.rng.normal(size=(n, 3))).clip(0.3, 3.0)
        rgb = self.rng.uniform(0.2, 0.8, size=(n, 3))
        self.parts.append((pts, _quat_z_to(self.unit(n), self.unit(n, 2)), scales,
                           self.rng.normal(-2.5, 1.0, n), rgb))

    def scene(self) -> GaussianScene:
        pts, quats, scales, logits, rgb = (np.concatenate(c) for c in zip(*self.parts))
        pts = _rotate(self.rotation, pts)
        quats = _qmul(np.broadcast_to(self.rotation, quats.shape), quats)
        return GaussianScene.from_arrays(
            means=pts, scales_log=_log(scales), quats=quats, opacity_logit=logits,
            sh_dc=(rgb - 0.5) / SH_C0, sh_rest=np.zeros((len(pts), 0, 3)))


def _turn(seed: int) -> np.ndarray:
    """The unit quaternion (w, x, y, z) the scene of ``seed`` is turned by (its own generator)."""
    q = np.random.default_rng([seed, 1]).normal(size=4)
    return q / np.sqrt((q * q).sum())


def up_of(name: str) -> np.ndarray:
    """Where the builder's up (+z) went in the file's frame: for the harness's test rigs only."""
    return _rotate(_turn(SEEDS[name]), np.array([[0.0, 0.0, 1.0]]))[0]


def _log(x: np.ndarray) -> np.ndarray:
    """ln x for the scales, by range reduction to [1, 2) and an atanh series (arithmetic only)."""
    m, e = np.frexp(x)
    m, e = m * 2.0, e - 1.0
    s = (m - 1.0) / (m + 1.0)
    s2, term, acc = s * s, s, np.zeros_like(s)
    for k in range(1, 40, 2):
        acc += term / k
        term = term * s2
    return 2.0 * acc + e * 0.6931471805599453


def _quat_z_to(normals: np.ndarray, spin: np.ndarray) -> np.ndarray:
    """(w, x, y, z) rotations taking +z to each normal, after a spin about z by the unit 2-vector
    (cos θ/2, sin θ/2) of ``spin``."""
    nx, ny, nz = normals.T
    w = 1.0 + nz
    flip = w < 1e-9
    q = np.stack([w, -ny, nx, np.zeros_like(w)], 1)
    q[flip] = (0.0, 1.0, 0.0, 0.0)
    q /= np.sqrt((q * q).sum(1, keepdims=True))
    about_z = np.stack([spin[:, 0], np.zeros(len(spin)), np.zeros(len(spin)), spin[:, 1]], 1)
    return _qmul(q, about_z)


def _qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    aw, ax, ay, az = a.T
    bw, bx, by, bz = b.T
    return np.stack([aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw], 1)


def _rotate(q: np.ndarray, p: np.ndarray) -> np.ndarray:
    return p @ quat_to_rotmat(q[None])[0].T


def _box(b: _Builder, lo, hi, density: float, colour, **kw) -> None:
    """The six faces of an axis-aligned box (z up), ``density`` splats per unit area."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    for axis in range(3):
        for side, sign in ((lo[axis], -1.0), (hi[axis], 1.0)):
            others = [k for k in range(3) if k != axis]
            area = float(np.prod(hi[others] - lo[others]))
            n = max(int(density * area), 8)
            pts = b.rng.uniform(lo, hi, size=(n, 3))
            pts[:, axis] = side
            nrm = np.zeros((n, 3))
            nrm[:, axis] = sign
            b.add(pts, nrm, area, colour, **kw)


def _cylinder(b: _Builder, base, radius: float, height: float, density: float, colour, **kw) -> None:
    area = 2 * 3.141592653589793 * radius * height
    n = max(int(density * area), 8)
    d = b.unit(n, 2)
    h = b.rng.uniform(0.0, height, n)
    pts = np.asarray(base, float) + np.stack([radius * d[:, 0], radius * d[:, 1], h], 1)
    b.add(pts, np.stack([d[:, 0], d[:, 1], np.zeros(n)], 1), area, colour, **kw)


def _ellipsoid(b: _Builder, centre, radii, density: float, colour, **kw) -> None:
    radii = np.asarray(radii, float)
    area = 4 * 3.141592653589793 * float(np.mean(radii)) ** 2
    n = max(int(density * area), 8)
    u = b.unit(n)
    nrm = u / radii
    b.add(np.asarray(centre, float) + u * radii, nrm / np.sqrt((nrm * nrm).sum(1, keepdims=True)), area, colour, **kw)


def _disc(b: _Builder, centre, radius: float, density: float, colour, **kw) -> None:
    area = 3.141592653589793 * radius * radius
    n = max(int(density * area), 8)
    r = radius * np.sqrt(b.rng.uniform(size=n))
    d = b.unit(n, 2)
    pts = np.asarray(centre, float) + np.stack([r * d[:, 0], r * d[:, 1], np.zeros(n)], 1)
    b.add(pts, np.tile([0.0, 0.0, 1.0], (n, 1)), area, colour, **kw)


def synth_room() -> GaussianScene:
    """A 6 × 5 × 2.8 room (z up in the builder's frame) with furniture and a subject on the table."""
    b = _Builder(SEEDS["synth-room"])
    lo, hi = np.array([-3.0, -2.5, 0.0]), np.array([3.0, 2.5, 2.8])
    floor = b.rng.uniform(lo, hi, size=(30000, 3))
    floor[:, 2] = 0.0
    b.add(floor, np.tile([0.0, 0.0, 1.0], (30000, 1)), 30.0, (0.55, 0.38, 0.22), freq=1.5, contrast=0.4)
    for axis in (0, 1):
        for side, sign in ((lo[axis], 1.0), (hi[axis], -1.0)):
            n = 14000
            pts = b.rng.uniform(lo, hi, size=(n, 3))
            pts[:, axis] = side
            nrm = np.zeros((n, 3))
            nrm[:, axis] = sign
            b.add(pts, nrm, float(np.prod([hi[k] - lo[k] for k in (1 - axis, 2)])), (0.82, 0.8, 0.74), freq=1.0)
    ceiling = b.rng.uniform(lo, hi, size=(6000, 3))
    ceiling[:, 2] = hi[2]
    b.add(ceiling, np.tile([0.0, 0.0, -1.0], (6000, 1)), 30.0, (0.9, 0.9, 0.88), contrast=0.1)
    _box(b, (-0.6, -0.4, 0.72), (0.6, 0.4, 0.76), 2500, (0.45, 0.28, 0.15), freq=4.0)  # table top
    for x in (-0.55, 0.5):
        for y in (-0.35, 0.3):
            _box(b, (x, y, 0.0), (x + 0.05, y + 0.05, 0.72), 1500, (0.4, 0.25, 0.13))
    _cylinder(b, (0.0, 0.0, 0.76), 0.08, 0.25, 12000, (0.2, 0.35, 0.6), freq=12.0)  # vase
    _ellipsoid(b, (0.0, 0.0, 1.12), (0.16, 0.16, 0.13), 9000, (0.25, 0.5, 0.2), freq=15.0, contrast=0.5)  # plant
    _ellipsoid(b, (0.3, 0.12, 0.81), (0.06, 0.06, 0.05), 9000, (0.8, 0.5, 0.1), freq=20.0)  # fruit
    _box(b, (2.3, -2.4, 0.0), (2.9, -1.2, 1.6), 1200, (0.6, 0.6, 0.55), freq=2.0)  # cabinet
    _box(b, (-1.6, 0.4, 0.0), (-1.15, 0.85, 0.45), 1800, (0.3, 0.3, 0.35))  # chair seat
    _box(b, (-1.6, 0.8, 0.45), (-1.15, 0.85, 0.95), 1800, (0.3, 0.3, 0.35))  # chair back
    b.floaters(1500, lo, hi, 0.03)
    return b.scene()


def synth_statue() -> GaussianScene:
    """A figure on a pedestal (z up in the builder's frame) on a 3 × 3 ground patch."""
    b = _Builder(SEEDS["synth-statue"])
    ground = b.rng.uniform((-1.5, -1.5, 0.0), (1.5, 1.5, 0.0), size=(25000, 3))
    b.add(ground, np.tile([0.0, 0.0, 1.0], (25000, 1)), 9.0, (0.35, 0.45, 0.2), freq=2.5, contrast=0.5)
    _box(b, (-0.3, -0.3, 0.0), (0.3, 0.3, 0.25), 9000, (0.6, 0.58, 0.55), freq=6.0)  # pedestal
    _cylinder(b, (-0.08, 0.0, 0.25), 0.05, 0.45, 9000, (0.55, 0.4, 0.3))  # legs
    _cylinder(b, (0.08, 0.0, 0.25), 0.05, 0.45, 9000, (0.55, 0.4, 0.3))
    _ellipsoid(b, (0.0, 0.0, 0.95), (0.17, 0.11, 0.27), 12000, (0.7, 0.2, 0.15), freq=10.0)  # torso
    _cylinder(b, (-0.22, 0.0, 0.75), 0.035, 0.4, 9000, (0.75, 0.6, 0.5))  # arms
    _cylinder(b, (0.22, 0.0, 0.75), 0.035, 0.4, 9000, (0.75, 0.6, 0.5))
    _ellipsoid(b, (0.0, 0.0, 1.35), (0.1, 0.1, 0.12), 14000, (0.85, 0.7, 0.6), freq=14.0)  # head
    _ellipsoid(b, (0.0, 0.0, 1.46), (0.11, 0.11, 0.04), 12000, (0.15, 0.1, 0.08), freq=20.0)  # hat
    b.floaters(600, (-1.5, -1.5, 0.0), (1.5, 1.5, 2.0), 0.02)
    return b.scene()


GENERATORS = {"synth-room": synth_room, "synth-statue": synth_statue}


def generate(name: str, path: Path) -> Path:
    """Write the generated scene ``name`` to ``path`` (binary little-endian PLY, INRIA layout)."""
    from harness.io.scenes import write_scene

    return write_scene(GENERATORS[name](), path, comments=[f"generated by harness.io.generated ({name})"])
