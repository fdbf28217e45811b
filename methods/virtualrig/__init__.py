"""``virtual-rig``: LightGaussian's significance without cameras, over a rig synthesised from the
splats alone (this project's own method, not the paper's; docs/virtual-rig.md).

    score_j = (V_j / V_ref)^v_pow · Σ_{virtual views} Σ_pixels o_j·T_j

the LightGS accumulation and volume term (:func:`methods.lightgs.significance.significance`,
:func:`~methods.lightgs.significance.volume_factor`) over the cameras of :mod:`.rig`, placed by the
scene-shape analysis of :mod:`.shape`: outside-in shells around an object, inside-out cubes of views
from the free space of a room. Nothing here imports the harness's test rigs (``harness.views``), so
the pruner cannot mirror the protocols that score it (``tests/test_virtualrig.py`` checks the import
graph).

Computed with the significance function's ``auto`` backend: the exact numba sweep on the CPU, the
reference rasterizer's statistics on the context's torch device elsewhere (CUDA), the rig's views
composited together there (:func:`renderers.reference.composite_views`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from harness.core.params import Params, param
from methods.registry import PruneContext, register_pruner


@dataclass(frozen=True)
class VirtualRigParams(Params):
    rig: Literal["auto", "outside-in", "inside-out"] = param(
        "auto", doc="auto = outside-in for an object, inside-out for a room (the scene-shape analysis); "
        "or force one")
    views: int = param(48, ge=1, le=1024, doc="virtual views (inside-out enclosed: cubes of 6, ⌈views/6⌉ positions)")
    shells: int = param(2, ge=1, le=16, doc="outside-in: concentric shells of cameras, equal shares of the views")
    radius_min: float = param(0.6, gt=0, le=10, doc="outside-in: distance of the closest shell, a multiple of "
                              "the fit distance R/sin(fov/2) (R: weighted P95 distance to the centre)")
    radius_max: float = param(1.0, gt=0, le=10, doc="outside-in: distance of the farthest shell (same unit)")
    fov_deg: float = param(60.0, ge=5, le=150, doc="field of view (inside-out enclosed cube faces: 90°)")
    resolution: int = param(384, ge=16, le=4096, doc="side of the square virtual views (px; 384 by the "
                            "pre-registered selection, results/virtualrig/selection.md)")
    grid: int = param(32, ge=8, le=256, doc="occupancy-grid cells along the content's longest side")
    positions: Literal["around", "coverage", "enclosed"] = param(
        "around", doc="inside-out cameras: around = along every direction from the subject (the opacity "
        "peak) at 0.7 of its free reach, looking at it; coverage = free-space positions within the content's "
        "median distance that see the subject, chosen greedily by the content their views add "
        "(methods/virtualrig/coverage.py; not adopted by the round-two selection, "
        "results/virtualrig/selection2.md); enclosed = cubes of six 90° views from the enclosed central free "
        "space (the first, pre-registered version: on bonsai-7k all below the table top)")
    support: Literal["auto", "off"] = param(
        "auto", doc="outside-in: auto = find the plane the content stands on (a dominant one-sided plane "
        "under the content's footprint, from the flat splats' normals; methods/virtualrig/support.py) and put "
        "no camera below it (adopted by the round-two selection and confirmation, "
        "results/virtualrig/confirmation2.md); off = the full sphere of directions")
    room_enclosure: float = param(0.8, gt=0, le=1, doc="median share of blocked rays from the central free "
                                  "space from which the scene is a room (inside-out)")
    rig_seed: int = param(0, ge=0, doc="seed of the rig's rotations and probe subsample (not the run's seed)")
    v_pow: float = param(0.1, ge=0, doc="exponent of the volume factor (V/V_ref)^v_pow (LightGaussian: 0.1)")
    early_stop: bool = param(True, doc="graphdeco's early termination at T < 1e-4, as LightGS's count pass")
    threads: int = param(1, ge=0, doc="torch intra-op threads while scoring (0 = unchanged)")


def virtual_cameras(scene, p: VirtualRigParams):
    """(shape, cameras) of the virtual rig of ``scene`` under ``p``."""
    from methods.virtualrig import rig
    from methods.virtualrig.shape import analyse

    shape = analyse(scene, grid=p.grid, room_enclosure=p.room_enclosure, seed=p.rig_seed)
    kind = {"auto": "inside-out" if shape.kind == "room" else "outside-in"}.get(p.rig, p.rig)
    if kind == "inside-out":
        return shape, rig.inside_out(shape, views=p.views, resolution=p.resolution, seed=p.rig_seed,
                                     positions=p.positions, room_enclosure=p.room_enclosure, fov_deg=p.fov_deg)
    ground = support_of(scene, shape, p)
    return shape, rig.outside_in(shape, views=p.views, shells=p.shells, radius_min=p.radius_min,
                                 radius_max=p.radius_max, fov_deg=p.fov_deg, resolution=p.resolution,
                                 seed=p.rig_seed, support=ground)


def support_of(scene, shape, p: VirtualRigParams):
    """The support plane the outside-in rig keeps its cameras above (None with ``support: off``)."""
    from methods.virtualrig.support import find_support

    if p.support == "off":
        return None
    return find_support(scene, shape.center, shape.radius, shape.cell, seed=p.rig_seed)


def rig_report(scene, p: VirtualRigParams):
    """(shape, support or None, cameras, a few lines saying what the rig found and where it put its views)."""
    shape, cams = virtual_cameras(scene, p)
    outside = bool(cams) and cams[0].name.startswith("vr_shell")
    ground = support_of(scene, shape, p) if outside else None
    lines = [f"scene shape: {shape.describe()}"]
    if ground is not None:
        lines.append(f"support: {ground.describe()}")
    lines.append(f"rig: {'outside-in' if outside else 'inside-out (' + p.positions + ')'}, {len(cams)} views of "
                 f"{p.resolution} px, field of view {p.fov_deg:g}°")
    return shape, ground, cams, "\n".join(lines)


def virtual_significance(scene, p: VirtualRigParams, device: str = "cpu") -> np.ndarray:
    """Σ o·T over the virtual rig (float64, (N,)), without the volume term."""
    from methods.lightgs.significance import significance
    from renderers.pixel_pairs import torch_threads

    _, cams = virtual_cameras(scene, p)
    with torch_threads(p.threads):
        return significance(scene, cams, longest_side=0, early_stop=p.early_stop, device=device, backend="auto")


@register_pruner("virtual-rig", params=VirtualRigParams, label="Virtual rig", group="camera-free",
                 uses_device=True)
def virtual_rig_score(scene, ctx: PruneContext) -> np.ndarray:
    """LightGS significance over a rig synthesised from the splats alone × (V/V_ref)^0.1 (no cameras)."""
    from methods.lightgs.significance import volume_factor

    p = ctx.params
    if len(scene) == 0:
        return np.zeros(0)
    return virtual_significance(scene, p, ctx.device) * volume_factor(scene.scales_log, p.v_pow)
