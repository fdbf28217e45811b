"""`GaussianScene`: a 3DGS scene as a structure of float32 arrays, plus explicit activations.

Stored (pre-activation) parameters, exactly as INRIA `.ply` files hold them:

* ``means``          (N, 3)   world positions
* ``scales_log``     (N, 3)   log of the per-axis standard deviations   -> :func:`scales` = exp
* ``quats``          (N, 4)   rotation quaternion (w, x, y, z), *not* normalised -> :func:`rotations`
* ``opacity_logit``  (N,)     logit of opacity                           -> :func:`opacities` = sigmoid
* ``sh_dc``          (N, 3)   SH degree-0 coefficient per colour channel
* ``sh_rest``        (N, K, 3) higher SH coefficients, K in {0, 3, 8, 15}, coefficient-major
  (the `.ply` stores them channel-major: ``f_rest_{c*K + k}``; readers/writers transpose)
* ``extra``          name -> (N,) array of any other per-splat property (``nx``, ``ny``, ...),
  carried through untouched in file order.
* ``meta``           :class:`SceneMeta`: where the scene came from (path, format) and its file's
  header comments (embedded cameras among them), kept by :meth:`subset` so that writers put them
  back (a pruned file is its input minus rows).

Activations are functions, never cached state, so a scene is just data.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

SH_C0 = 0.28209479177387814
#: number of higher-order SH coefficients per channel for degrees 0..3
SH_REST_COUNT = {0: 0, 1: 3, 2: 8, 3: 15}
_DEGREE_OF_REST = {k: d for d, k in SH_REST_COUNT.items()}


@dataclass(frozen=True)
class SceneMeta:
    """What a scene's file said besides the splats.

    ``comments`` are header comment texts in file order, each with whether it stood before the
    PLY ``format`` line (``preamble``: where MPEG tools put ``camera_position`` lines) or after it.
    """

    source: str = ""        # the path it was read from ("" for a scene built in memory)
    format: str = ""        # the reader's format name ("ply", "splat", "sog", ...)
    preamble: tuple[str, ...] = ()   # comments before the `format` line
    comments: tuple[str, ...] = ()   # comments after it (obj_info lines included, as written)

    @property
    def all_comments(self) -> tuple[str, ...]:
        return self.preamble + self.comments


@dataclass
class GaussianScene:
    means: np.ndarray
    scales_log: np.ndarray
    quats: np.ndarray
    opacity_logit: np.ndarray
    sh_dc: np.ndarray
    sh_rest: np.ndarray
    extra: dict[str, np.ndarray] = field(default_factory=dict)
    meta: SceneMeta = field(default_factory=SceneMeta)

    def __post_init__(self) -> None:
        why = shape_problem(self)
        if why:
            raise ValueError(why)

    # ------------------------------------------------------------------ shape facts
    def __len__(self) -> int:
        return len(self.means)

    @property
    def sh_degree(self) -> int:
        return _DEGREE_OF_REST[self.sh_rest.shape[1]]

    @property
    def nbytes(self) -> int:
        core = (self.means, self.scales_log, self.quats, self.opacity_logit, self.sh_dc, self.sh_rest)
        return int(sum(a.nbytes for a in core) + sum(a.nbytes for a in self.extra.values()))

    # ------------------------------------------------------------------ constructors
    @classmethod
    def from_arrays(
        cls,
        means,
        scales_log,
        quats,
        opacity_logit,
        sh_dc,
        sh_rest=None,
        extra: dict[str, np.ndarray] | None = None,
        meta: SceneMeta | None = None,
    ) -> "GaussianScene":
        """Build a scene, casting every core array to contiguous float32."""
        f32 = lambda a: np.ascontiguousarray(a, dtype=np.float32)  # noqa: E731
        means = f32(means)
        if sh_rest is None:
            sh_rest = np.zeros((len(means), 0, 3), np.float32)
        return cls(
            means=means,
            scales_log=f32(scales_log),
            quats=f32(quats),
            opacity_logit=f32(opacity_logit).reshape(-1),
            sh_dc=f32(sh_dc),
            sh_rest=f32(sh_rest),
            extra=dict(extra or {}),
            meta=meta or SceneMeta(),
        )

    def subset(self, index) -> "GaussianScene":
        """Rows selected by a boolean mask or an index array (order preserved), extras and meta included."""
        index = np.asarray(index)
        return GaussianScene(
            means=self.means[index],
            scales_log=self.scales_log[index],
            quats=self.quats[index],
            opacity_logit=self.opacity_logit[index],
            sh_dc=self.sh_dc[index],
            sh_rest=self.sh_rest[index],
            extra={k: v[index] for k, v in self.extra.items()},
            meta=self.meta,
        )

    def with_meta(self, **changes) -> "GaussianScene":
        """The same arrays with :class:`SceneMeta` fields replaced."""
        return GaussianScene(self.means, self.scales_log, self.quats, self.opacity_logit, self.sh_dc,
                             self.sh_rest, self.extra, replace(self.meta, **changes))

    def with_sh_degree(self, degree: int) -> "GaussianScene":
        """The same scene truncated to ``degree`` (never raises the degree)."""
        k = SH_REST_COUNT[min(degree, self.sh_degree)]
        return GaussianScene(
            self.means, self.scales_log, self.quats, self.opacity_logit, self.sh_dc,
            np.ascontiguousarray(self.sh_rest[:, :k]), dict(self.extra), self.meta,
        )


# ---------------------------------------------------------------------- activations
#: the core arrays of a scene, in file order
CORE = ("means", "scales_log", "quats", "opacity_logit", "sh_dc", "sh_rest")


def shape_problem(scene: GaussianScene) -> str | None:
    """Why the scene's arrays do not make one scene of ``len(scene.means)`` splats, or None: means
    (N, 3), scales_log (N, 3), quats (N, 4), opacity_logit (N,), sh_dc (N, 3), sh_rest (N, K, 3)
    with K in 0, 3, 8, 15, each extra property N rows. Checked when a scene is made, and again by
    :func:`harness.core.validate.validate` on a scene whose arrays were replaced since."""
    if not all(isinstance(getattr(scene, a, None), np.ndarray) for a in CORE):
        bad = next(a for a in CORE if not isinstance(getattr(scene, a, None), np.ndarray))
        return f"{bad} is a {type(getattr(scene, bad, None)).__name__}, not a numpy array"
    n = len(scene.means)
    shapes = {"means": (n, 3), "scales_log": (n, 3), "quats": (n, 4), "opacity_logit": (n,), "sh_dc": (n, 3)}
    for name, shape in shapes.items():
        arr = getattr(scene, name)
        if arr.shape != shape:
            return f"{name} has shape {arr.shape}, expected {shape}"
    if scene.sh_rest.ndim != 3 or scene.sh_rest.shape[0] != n or scene.sh_rest.shape[2] != 3:
        return f"sh_rest has shape {scene.sh_rest.shape}, expected ({n}, K, 3)"
    if scene.sh_rest.shape[1] not in _DEGREE_OF_REST:
        return f"sh_rest has {scene.sh_rest.shape[1]} coefficients; expected 0, 3, 8 or 15"
    for name, arr in scene.extra.items():
        if not isinstance(arr, np.ndarray) or arr.shape[:1] != (n,):
            return f"extra property {name!r} must be an array of {n} rows, got shape {getattr(arr, 'shape', None)}"
    return None


def sigmoid(x: np.ndarray) -> np.ndarray:
    """Numerically stable logistic function, same dtype as ``x``."""
    x = np.asarray(x)
    out = np.empty_like(x, dtype=np.result_type(x, np.float32))
    pos = x >= 0
    out[pos] = 1.0 / (1.0 + np.exp(-x[pos]))
    ex = np.exp(x[~pos])
    out[~pos] = ex / (1.0 + ex)
    return out


def opacities(scene: GaussianScene) -> np.ndarray:
    """o = sigmoid(opacity_logit), (N,)."""
    return sigmoid(scene.opacity_logit)


def scales(scene: GaussianScene) -> np.ndarray:
    """Per-axis standard deviations s = exp(scales_log), (N, 3)."""
    return np.exp(scene.scales_log)


def normalized_quats(quats: np.ndarray) -> np.ndarray:
    """Unit quaternions (w, x, y, z). Zero-norm rows become the identity rotation."""
    q = np.asarray(quats, dtype=np.float64)
    norm = np.linalg.norm(q, axis=-1, keepdims=True)
    out = np.where(norm > 0, q / np.where(norm > 0, norm, 1.0), np.array([1.0, 0.0, 0.0, 0.0]))
    return out.astype(quats.dtype if np.issubdtype(quats.dtype, np.floating) else np.float64)


def quat_to_rotmat(quats: np.ndarray) -> np.ndarray:
    """Rotation matrices (N, 3, 3) from (w, x, y, z) quaternions, normalised on use."""
    w, x, y, z = np.moveaxis(normalized_quats(quats), -1, 0)
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        -2,
    )


def rotations(scene: GaussianScene) -> np.ndarray:
    """R_i (N, 3, 3); columns are the splat's local axes in world space."""
    return quat_to_rotmat(scene.quats)


def bounding_box(scene: GaussianScene) -> tuple[np.ndarray, np.ndarray, float]:
    """(min, max, diagonal length) of the splat centres; an empty scene gives zeros."""
    if len(scene) == 0:
        z = np.zeros(3)
        return z, z, 0.0
    lo = scene.means.min(0).astype(np.float64)
    hi = scene.means.max(0).astype(np.float64)
    return lo, hi, float(np.linalg.norm(hi - lo))


def base_colors(scene: GaussianScene) -> np.ndarray:
    """View-independent colour 0.5 + SH_C0 · f_dc, clamped at 0 (N, 3)."""
    return np.maximum(0.5 + SH_C0 * scene.sh_dc, 0.0)
