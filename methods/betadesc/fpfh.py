"""Fast Point Feature Histograms (Rusu 2009), numerically the same as open3d's.

``compute_fpfh(points, normals, radius, max_nn)`` reproduces
``open3d.pipelines.registration.compute_fpfh_feature(pcd, KDTreeSearchParamHybrid(radius, max_nn))``
(open3d 0.19/0.20 ``Feature.cpp``), transposed to (M, 33):

* Neighbours N(i): the hybrid search of :mod:`.neighbors` (max_nn nearest *including i itself*, with
  ``d² < r²``); slot 0 (i itself) is skipped, so at most ``max_nn - 1`` neighbours take part.
* Pair features of (p₁, n₁) = (p_i, n_i), (p₂, n₂) = (p_j, n_j), d = ‖p₂ − p₁‖ (all zero if d = 0):
  a₁ = n₁·(p₂−p₁)/d, a₂ = n₂·(p₂−p₁)/d; if |a₁| < |a₂| the roles swap (source = the point whose
  normal is more aligned with the line; dp flips sign) and θ = −a₂, else θ = a₁.
  v = dp × n₁ / ‖dp × n₁‖ (all zero if that norm is 0), w = n₁ × v, φ = v·n₂,
  α = atan2(w·n₂, n₁·n₂).
* SPFH_i: bins ``floor(11(α+π)/2π)``, ``floor(11(φ+1)/2)``, ``floor(11(θ+1)/2)``, each clamped to
  [0, 10], blocks 0–10 / 11–21 / 22–32, every pair adding 100/|N(i)| to one bin of each block
  (so each block sums to 100, or is all zero for an isolated point). Degenerate pairs (d = 0 or dp ∥ n₁)
  give α = φ = θ = 0, i.e. bin 5 of each block.
* FPFH_i = SPFH_i + (per block) 100 · Σ_j SPFH_j / d²_ij ⁄ Σ_j Σ_block SPFH_j / d²_ij over N(i), with
  pairs at d² = 0 left out of the sum — the weight is the *squared* distance (open3d passes the
  kd-tree's d² straight through). A point with no neighbour gets an all-zero row.

Tolerance (tested against open3d): max |ours − open3d| ≤ 1e-9 on histogram values of scale 100
(observed ~1e-13), from summation order and multiplying by a reciprocal 1/d² once instead of 33
divisions. Exact distance ties at the max_nn boundary (e.g. points on a regular lattice) make both
searches pick arbitrary, possibly different neighbours — then rows can differ by whole bins; tests use
tie-free clouds. A pair whose angle lands within ~1 ulp of a bin edge could in principle bin
differently if the compiler rounds differently (never observed).

Speed (see ``harness bench fpfh``): one search serves SPFH and FPFH (open3d searches twice); the
α bin comes from a polynomial atan2 with an exact fallback near bin edges; SPFH runs in short passes
over a row's neighbours; the FPFH stage multiplies by 1/d² once per neighbour. Each output row is
written once into an uninitialised array (a zeroed array that is read-modify-written faults twice
per fresh page, which on these VMs cost more than the arithmetic). SPFH is bound by the divider:
5 divisions and 2 square roots per pair, which must be true divisions to bin exactly as open3d
(a structure-of-arrays rewrite that LLVM vectorised to AVX2 ran no faster).

Parallel over chunks of points with ``prange`` and no cross-thread reductions: bit-identical for any
numba thread count. Everything is float64; translation is harmless up to float64 resolution of the inputs
(the geometry uses only differences p₂ − p₁).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from methods.betadesc.neighbors import Neighborhood, hybrid_search

#: default neighbourhood in voxel units for the voxel clouds of BetaDescPrune (open3d's registration
#: tutorial uses radius = 5 voxels); max_nn includes the point itself.
DEFAULT_RADIUS_VOXELS = 5.0
DEFAULT_MAX_NN = 64
N_BINS = 11
FPFH_DIM = 3 * N_BINS


# atan(z) ≈ z·Q(z²) on [0, 1], least-squares fit, max error 2.9e-7 (checked on a 2e6-point grid)
Q0, Q1, Q2, Q3, Q4, Q5, Q6 = (
    0.9999956232907636,
    -0.33316001767956793,
    0.19796889889209252,
    -0.13195894173480005,
    0.07899968587630037,
    -0.03310512196374987,
    0.006658246628586639,
)
#: a bin is trusted from the approximation only if the angle is this far (rad) from a bin edge
_ALPHA_MARGIN = 1e-5
_MARGIN_T = _ALPHA_MARGIN * (11.0 / (2.0 * math.pi))  # the same in bin units
_CHUNKS = 64  # points are processed in this many independent chunks (any thread count)


@nb.njit(cache=True, fastmath=False, inline="always")
def _alpha_bin_exact(y, x):
    h = math.floor(11 * (math.atan2(y, x) + math.pi) / (2.0 * math.pi))
    return min(max(h, 0), 10)


@nb.njit(cache=True, fastmath=False, inline="always")
def _alpha_bin_fast(y, x):
    """open3d's α bin ``clamp(floor(11(atan2(y, x) + π)/2π), 0, 10)``, or −1 when unsure.

    A polynomial atan2 (error < 3e-7 rad) decides the bin when the angle is more than
    ``_ALPHA_MARGIN`` = 1e-5 rad from every bin edge — then the exact angle is in the same bin.
    Near an edge (about 3 pairs in 10⁵) or on an axis (x or y zero: the signed-zero cases) it
    returns −1 and the caller uses the exact libm ``atan2`` and open3d's expression. Written with
    selects only: the signs are coin flips for a branch predictor.
    """
    ax = abs(x)
    ay = abs(y)
    big = max(ax, ay)
    z = min(ax, ay) / (big if big > 0.0 else 1.0)
    s = z * z
    a = z * ((((((Q6 * s + Q5) * s + Q4) * s + Q3) * s + Q2) * s + Q1) * s + Q0)
    a = 0.5 * math.pi - a if ay > ax else a
    a = math.pi - a if x < 0.0 else a
    a = math.copysign(a, y)
    t = (a + math.pi) * (11.0 / (2.0 * math.pi))
    h = math.floor(t)
    unsure = (t - h < _MARGIN_T) | (h + 1.0 - t < _MARGIN_T) | (ax == 0.0) | (ay == 0.0)
    return -1 if unsure else min(max(int(h), 0), 10)


def _alpha_bin(y: float, x: float) -> int:
    """The α bin as the kernel decides it (fast path, exact fallback); for tests."""
    h = _alpha_bin_fast(y, x)
    return _alpha_bin_exact(y, x) if h < 0 else h


@nb.njit(parallel=True, cache=True, fastmath=False)
def _spfh_kernel(p, nrm, index, count, out):
    """SPFH rows in three passes over a row's neighbours.

    One pass per pair would be one long dependent chain (sqrt → divide → cross → sqrt → divide →
    polynomial) that leaves the out-of-order core idle; short passes over all neighbours keep many
    independent pairs in flight (about 3× faster, same arithmetic, same bits). ``dist`` is
    ``sqrt((dx² + dy²) + dz²)``, the search's d² (squares of p₂ − p₁ equal those of p₁ − p₂
    exactly) and the same float as open3d's ``(p₂ − p₁).norm()``.
    """
    m = p.shape[0]
    kmax = index.shape[1]
    chunk = (m + _CHUNKS - 1) // _CHUNKS
    for ch in nb.prange(_CHUNKS):
        # per pair: u (source normal) 0-2, t (target normal) 3-5, v = dp × u 6-8 (later y, x),
        # θ 9, dist 10, ok 11
        buf = np.empty((12, kmax))
        bins = np.empty((3, kmax), np.int64)
        row = np.empty(FPFH_DIM)
        for i in range(ch * chunk, min(m, (ch + 1) * chunk)):
            c = count[i]
            for b in range(FPFH_DIM):
                row[b] = 0.0
            if c <= 1:
                for b in range(FPFH_DIM):
                    out[i, b] = 0.0
                continue
            p1x, p1y, p1z = p[i, 0], p[i, 1], p[i, 2]
            m1x, m1y, m1z = nrm[i, 0], nrm[i, 1], nrm[i, 2]
            for k in range(1, c):  # pass 1: source/target and v = dp × u
                j = index[i, k]
                dx = p[j, 0] - p1x
                dy = p[j, 1] - p1y
                dz = p[j, 2] - p1z
                dist = math.sqrt(dx * dx + dy * dy + dz * dz)
                sd = dist if dist != 0.0 else 1.0
                m2x, m2y, m2z = nrm[j, 0], nrm[j, 1], nrm[j, 2]
                a1 = (m1x * dx + m1y * dy + m1z * dz) / sd
                a2 = (m2x * dx + m2y * dy + m2z * dz) / sd
                sw = abs(a1) < abs(a2)  # source = the normal more aligned with the line
                ux = m2x if sw else m1x
                uy = m2y if sw else m1y
                uz = m2z if sw else m1z
                sg = -1.0 if sw else 1.0
                ex = dx * sg
                ey = dy * sg
                ez = dz * sg
                buf[0, k] = ux
                buf[1, k] = uy
                buf[2, k] = uz
                buf[3, k] = m1x if sw else m2x
                buf[4, k] = m1y if sw else m2y
                buf[5, k] = m1z if sw else m2z
                buf[6, k] = ey * uz - ez * uy
                buf[7, k] = ez * ux - ex * uz
                buf[8, k] = ex * uy - ey * ux
                buf[9, k] = -a2 if sw else a1
                buf[10, k] = dist
            for k in range(1, c):  # pass 2: v̂, w = u × v̂, φ, θ bins; α's (y, x)
                vx, vy, vz = buf[6, k], buf[7, k], buf[8, k]
                vn = math.sqrt(vx * vx + vy * vy + vz * vz)
                ok = (buf[10, k] != 0.0) & (vn != 0.0)  # else the pair's features are all 0
                svn = vn if ok else 1.0
                vx /= svn
                vy /= svn
                vz /= svn
                ux, uy, uz = buf[0, k], buf[1, k], buf[2, k]
                tx, ty, tz = buf[3, k], buf[4, k], buf[5, k]
                wx = uy * vz - uz * vy
                wy = uz * vx - ux * vz
                wz = ux * vy - uy * vx
                phi = vx * tx + vy * ty + vz * tz if ok else 0.0
                theta = buf[9, k] if ok else 0.0
                buf[6, k] = wx * tx + wy * ty + wz * tz
                buf[7, k] = ux * tx + uy * ty + uz * tz
                buf[11, k] = 1.0 if ok else 0.0
                bins[1, k] = min(max(math.floor(11 * (phi + 1.0) * 0.5), 0), 10)
                bins[2, k] = min(max(math.floor(11 * (theta + 1.0) * 0.5), 0), 10)
            for k in range(1, c):  # pass 3: α bins (5 = the bin of α = 0 for degenerate pairs)
                h = _alpha_bin_fast(buf[6, k], buf[7, k])
                bins[0, k] = h if buf[11, k] != 0.0 else 5
            incr = 100.0 / (c - 1)
            for k in range(1, c):
                h = bins[0, k]
                if h < 0:
                    h = _alpha_bin_exact(buf[6, k], buf[7, k])
                row[h] += incr
                row[11 + bins[1, k]] += incr
                row[22 + bins[2, k]] += incr
            for b in range(FPFH_DIM):
                out[i, b] = row[b]


@nb.njit(parallel=True, cache=True, fastmath=False)
def _fpfh_kernel(spfh, p, index, count, out):
    m = spfh.shape[0]
    # a run-time trip count lets LLVM's loop vectoriser (with its alias check) take the 33-bin
    # loop; a constant one is unrolled to scalars instead (1.7× slower here)
    dim = spfh.shape[1]
    chunk = (m + _CHUNKS - 1) // _CHUNKS
    for ch in nb.prange(_CHUNKS):
        acc = np.empty(dim)
        for i in range(ch * chunk, min(m, (ch + 1) * chunk)):
            c = count[i]
            if c <= 1:
                for b in range(dim):
                    out[i, b] = 0.0
                continue
            for b in range(dim):  # a loop, not a slice assignment: numba's slices cost ~0.1 µs
                acc[b] = 0.0
            px, py, pz = p[i, 0], p[i, 1], p[i, 2]
            for k in range(1, c):
                j = index[i, k]
                dx = px - p[j, 0]
                dy = py - p[j, 1]
                dz = pz - p[j, 2]
                d = dx * dx + dy * dy + dz * dz  # the search's d², bit for bit
                if d == 0.0:
                    continue
                w = 1.0 / d
                for b in range(dim):
                    acc[b] += spfh[j, b] * w
            for blk in range(3):
                s = 0.0
                for b in range(blk * N_BINS, (blk + 1) * N_BINS):
                    s += acc[b]
                scale = 100.0 / s if s != 0.0 else 0.0
                for b in range(blk * N_BINS, (blk + 1) * N_BINS):
                    out[i, b] = acc[b] * scale + spfh[i, b]


def compute_spfh(points: np.ndarray, normals: np.ndarray, nbh: Neighborhood) -> np.ndarray:
    """Simplified PFH (M, 33) on precomputed neighbourhoods (see the module docstring)."""
    p, n = _check(points, normals)
    out = np.empty((len(p), FPFH_DIM))  # every row is written once (a fresh page faults once)
    if len(p):
        _spfh_kernel(p, n, nbh.index, nbh.count, out)
    return out


def compute_fpfh(
    points: np.ndarray,
    normals: np.ndarray,
    radius: float,
    max_nn: int = DEFAULT_MAX_NN,
    neighbors: Neighborhood | None = None,
) -> np.ndarray:
    """FPFH (M, 33) float64, equal to open3d's ``compute_fpfh_feature`` (hybrid search) transposed.

    ``neighbors`` may pass a :func:`~.neighbors.hybrid_search` result for the same points, radius and
    max_nn to share one search with other stages. Normals are used as given (open3d does not
    normalise them either); their signs matter — see :mod:`.normals`.
    """
    p, n = _check(points, normals)
    nbh = hybrid_search(p, radius, max_nn) if neighbors is None else neighbors
    if len(nbh) != len(p) or nbh.radius != float(radius) or nbh.max_nn != int(max_nn):
        raise ValueError("neighbors were computed for other points or search parameters")
    return fpfh_from_spfh(compute_spfh(p, n, nbh), nbh)


def fpfh_from_spfh(spfh: np.ndarray, nbh: Neighborhood) -> np.ndarray:
    """FPFH (M, 33) from SPFH rows and the same neighbourhoods (the distance-weighted stage)."""
    out = np.empty_like(spfh)  # every row is written
    if len(spfh):
        _fpfh_kernel(spfh, nbh.points, nbh.index, nbh.count, out)
    return out


def _check(points, normals) -> tuple[np.ndarray, np.ndarray]:
    p = np.ascontiguousarray(points, dtype=np.float64)
    n = np.ascontiguousarray(normals, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3 or n.shape != p.shape:
        raise ValueError(f"points and normals must both be (M, 3), got {p.shape} and {n.shape}")
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(n))):
        raise ValueError("points or normals contain NaN or inf")
    return p, n
