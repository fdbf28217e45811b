"""Render-free diagnostics: why a pruner wins or loses, without rendering a pruned image.

For a scene, a pruner (and its parameters) and a pruning ratio R:

* **correlations** — Spearman's ρ between LightGaussian's global significance (the ``lightgs``
  pruner's score: Σ_views Σ_pixels o·T × (V/V_ref)^0.1 over the scene's default-rig *training*
  views; the closest render-free stand-in for "what the images need") and each per-splat quantity
  of the pruner: for the BetaDesc family s, ℓ, o, u, w, A, B and the final score
  (:func:`methods.betadesc.pipeline.components`), for any other pruner its score. ρ is ``None``
  where a quantity is constant.
* **removal** at R (exactly round(R·N) lowest scores, ties by index, as every run):
  ``significance_removed`` = Σ_removed significance / Σ significance; ``opacity_volume_removed`` =
  Σ_removed o·V / Σ o·V with o = sigmoid(opacity) and V = Π exp(scales); ``region_removed`` = the
  fraction of the removed splats that come from voxels losing more than 90 % of their splats (voxel
  = ``voxel`` × bounding-box diagonal, the BetaDesc grid; 1 − region_removed is "thinning"), and
  ``voxels_emptied`` = the fraction of occupied voxels losing > 90 %.

Random pruning removes ≈ R of the significance and of o·V and almost never empties a voxel; a good
pruner removes far less significance than R.

It lives beside the pruners it runs (it reads BetaDesc's components and grid); the training views
come from the caller (``harness diagnose``: :func:`harness.views.rigs.training_views`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from harness.core.scene import GaussianScene, opacities

REGION_SHARE = 0.9
BETADESC_FAMILY = {"betadesc": (True, True), "betadesc-nobeta": (True, False),
                   "betadesc-nodesc": (False, True), "betadesc-nodesc-nobeta": (False, False)}


@dataclass
class Diagnosis:
    method: str
    params: dict
    ratio: float
    removed: int
    correlations: dict[str, float | None] = field(default_factory=dict)
    significance_removed: float = float("nan")
    opacity_volume_removed: float = float("nan")
    region_removed: float = float("nan")
    voxels_emptied: float = float("nan")
    label: str = ""  # how the caller named it (e.g. "betadesc:reading=v1")

    def to_dict(self) -> dict:
        return dict(self.__dict__)


def spearman(x: np.ndarray, y: np.ndarray) -> float | None:
    """Spearman's ρ, ``None`` when either side is constant (or there are fewer than 2 values)."""
    x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
    if x.size < 2 or np.ptp(x) == 0 or np.ptp(y) == 0:
        return None
    return float(stats.spearmanr(x, y)[0])


def opacity_volume(scene: GaussianScene) -> np.ndarray:
    """o·V per splat, float64 (V = Π exp(scales_log))."""
    return opacities(scene).astype(np.float64) * np.exp(scene.scales_log.astype(np.float64).sum(axis=1))


def removal(scene: GaussianScene, removed: np.ndarray, significance: np.ndarray,
            voxel: float = 0.01) -> dict[str, float]:
    """The removal shares of module docstring for a boolean ``removed`` mask."""
    from methods.betadesc.grid import build_grid

    removed = np.asarray(removed, bool)
    sig = np.asarray(significance, np.float64)
    ov = opacity_volume(scene)
    out = {"significance_removed": float(sig[removed].sum() / sig.sum()) if sig.sum() > 0 else float("nan"),
           "opacity_volume_removed": float(ov[removed].sum() / ov.sum()) if ov.sum() > 0 else float("nan")}
    if len(scene) == 0 or not removed.any():
        return {**out, "region_removed": 0.0, "voxels_emptied": 0.0}
    grid = build_grid(scene.means, voxel)
    lost = np.bincount(grid.splat_voxel, weights=removed.astype(np.float64), minlength=grid.m) / grid.counts
    emptied = lost > REGION_SHARE
    out["region_removed"] = float(emptied[grid.splat_voxel[removed]].mean())
    out["voxels_emptied"] = float(emptied.mean())
    return out


def quantities(scene: GaussianScene, method: str, params: dict, *, cameras=None, seed: int = 0,
               device: str = "cpu") -> dict[str, np.ndarray]:
    """Per-splat quantities of a pruner: the BetaDesc family's components, else ``{"score": …}``."""
    from methods.registry import PruneContext, get_pruner

    spec = get_pruner(method)
    resolved = spec.parse_params(params)
    if method in BETADESC_FAMILY:
        from methods.betadesc.pipeline import components

        descriptors, beta = BETADESC_FAMILY[method]
        cams = cameras if spec.wants_cameras(resolved) else None
        c = components(scene, resolved, cams, descriptors=descriptors, beta=beta)
        out = {"s": c.s, "ell": c.ell, "o": c.o, "u": c.u, "w": c.w, "A": c.a, "B": c.b, "score": c.score}
        return out if descriptors else {k: v for k, v in out.items() if k not in ("w",)}
    cams = cameras if spec.wants_cameras(resolved) else None
    return {"score": spec.score(scene, PruneContext(params=resolved, seed=seed, cameras=cams, device=device))}


def diagnose(scene: GaussianScene, method: str, params: dict, ratio: float, significance: np.ndarray, *,
             cameras=None, voxel: float | None = None, seed: int = 0, device: str = "cpu",
             score: np.ndarray | None = None) -> Diagnosis:
    """Correlations with ``significance`` and removal shares at ``ratio`` for one pruner (``score``:
    its already computed scores, e.g. the significance itself for ``lightgs``)."""
    from methods.registry import get_pruner
    from methods.targeting import select_by_ratio

    if score is None:
        q = quantities(scene, method, params, cameras=cameras, seed=seed, device=device)
    else:
        q = {"score": np.asarray(score, np.float64)}
    resolved = get_pruner(method).parse_params(params)
    if voxel is None:
        voxel = getattr(resolved, "voxel", 0.01)
    sel = select_by_ratio(q["score"], ratio)
    d = Diagnosis(method, resolved.to_dict(), ratio, sel.removed,
                  {k: spearman(v, significance) for k, v in q.items()})
    for k, v in removal(scene, ~sel.keep, significance, voxel).items():
        setattr(d, k, v)
    return d


def lightgs_significance(scene: GaussianScene, cameras, *, longest_side: int = 512,
                         device: str = "cpu") -> np.ndarray:
    """The ``lightgs`` pruner's score (its default parameters but the render size)."""
    from methods.registry import PruneContext, get_pruner

    spec = get_pruner("lightgs")
    params = spec.parse_params({"train_longest_side": longest_side})
    return spec.score(scene, PruneContext(params=params, cameras=cameras, device=device))


def _share(v: float) -> str:
    """A share as a percentage; ``n/a`` where it is undefined (a total of 0: NaN), never ``nan%``."""
    return f"{v:.1%}" if np.isfinite(v) else "n/a"


def format_text(scene_name: str, n: int, diagnoses: list[Diagnosis]) -> str:
    """A plain-text report: one correlation block and one removal line per pruner."""
    lines = [f"{scene_name}: {n:,} splats; ρ = Spearman with LightGS significance; removal at ratio "
             f"{diagnoses[0].ratio:g} (random ≈ {diagnoses[0].ratio:.0%} of significance and o·V)"]
    for d in diagnoses:
        lines.append(f"\n{d.label or d.method}")
        lines.append("  ρ: " + "  ".join(f"{k} {('  n/a' if v is None else f'{v:+.3f}')}"
                                        for k, v in d.correlations.items()))
        lines.append(f"  removed {d.removed:,}: significance {_share(d.significance_removed)}, "
                     f"opacity·volume {_share(d.opacity_volume_removed)}, from voxels losing > 90 % "
                     f"{_share(d.region_removed)} (voxels emptied {_share(d.voxels_emptied)})")
    return "\n".join(lines)
