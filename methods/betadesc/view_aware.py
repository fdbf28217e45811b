"""Optional view-aware features and the edge proxy e_i (the paper's §3.1–3.2), used only when the
context holds cameras; without cameras nothing here runs and the method is camera-agnostic.

Per splat i and camera c with centre C_c and forward axis f_c, the splat is *visible* to c when
its centre is in front of the camera (z > 0.2, the renderer's near cut) and projects inside the
image. With n_i the splat's shortest scale axis (its normal), a_i its longest axis, diag the
bounding-box diagonal and v̂ = (x_i − C_c)/‖x_i − C_c‖:

    d = ‖x_i − C_c‖ / diag     (relative distance)
    cn = |n_i · v̂|             (normal–view alignment; 0 = grazing)
    cf = |a_i · f_c|           (orientation–forward alignment)

The 10 features, over the cameras that see the splat (all 0 when none does):

    0 visible fraction        1 mean d     2 min d      3 std d
    4 mean cn                 5 min cn     6 max cn     7 std cn
    8 mean cf                 9 max cf

Edge proxy: e_i = o_i · (fraction of the visible views where cn < 0.3), the opacity-weighted
share of grazing views — opaque splats seen edge-on sit on silhouettes and contours. It enters
the retention evidence as ``A += view_weight · e_i`` (:mod:`methods.betadesc.evidence`).
"""

from __future__ import annotations

import numpy as np

from harness.core.scene import GaussianScene, bounding_box, quat_to_rotmat

N_FEATURES = 10
GRAZING_COS = 0.3
NEAR = 0.2


def view_statistics(scene: GaussianScene, cameras) -> tuple[np.ndarray, np.ndarray]:
    """The 10 view-alignment features (N, 10) and the grazing share of visible views (N,)."""
    n = len(scene)
    x = scene.means.astype(np.float64)
    rot = quat_to_rotmat(scene.quats).astype(np.float64)
    order = np.argsort(scene.scales_log, axis=1)
    normal = rot[np.arange(n), :, order[:, 0]]
    longest = rot[np.arange(n), :, order[:, 2]]
    diag = bounding_box(scene)[2] or 1.0
    sums = np.zeros((n, 7))  # visible count, Σd, Σd², Σcn, Σcn², Σcf, grazing count
    mins = np.full((n, 2), np.inf)  # min d, min cn
    maxs = np.zeros((n, 2))  # max cn, max cf
    for cam in cameras:
        pc = x @ cam.rotation.T + cam.translation
        z = pc[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            u = cam.fx * pc[:, 0] / z + cam.cx
            v = cam.fy * pc[:, 1] / z + cam.cy
        vis = (z > NEAR) & (u >= 0) & (u < cam.width) & (v >= 0) & (v < cam.height)
        ray = x - cam.center
        dist = np.linalg.norm(ray, axis=1)
        view = ray / np.maximum(dist, 1e-300)[:, None]
        d = dist / diag
        cn = np.abs(np.einsum("ij,ij->i", normal, view))
        cf = np.abs(longest @ cam.forward)
        vf = vis.astype(np.float64)
        sums[:, 0] += vf
        sums[:, 1] += vf * d
        sums[:, 2] += vf * d * d
        sums[:, 3] += vf * cn
        sums[:, 4] += vf * cn * cn
        sums[:, 5] += vf * cf
        sums[:, 6] += vf * (cn < GRAZING_COS)
        mins[:, 0] = np.where(vis, np.minimum(mins[:, 0], d), mins[:, 0])
        mins[:, 1] = np.where(vis, np.minimum(mins[:, 1], cn), mins[:, 1])
        maxs[:, 0] = np.where(vis, np.maximum(maxs[:, 0], cn), maxs[:, 0])
        maxs[:, 1] = np.where(vis, np.maximum(maxs[:, 1], cf), maxs[:, 1])
    k = sums[:, 0]
    seen = k > 0
    kk = np.where(seen, k, 1.0)
    mean_d, mean_cn = sums[:, 1] / kk, sums[:, 3] / kk
    feats = np.zeros((n, N_FEATURES))
    feats[:, 0] = k / max(len(cameras), 1)
    feats[:, 1] = mean_d
    feats[:, 2] = np.where(seen, mins[:, 0], 0.0)
    feats[:, 3] = np.sqrt(np.maximum(sums[:, 2] / kk - mean_d ** 2, 0.0))
    feats[:, 4] = mean_cn
    feats[:, 5] = np.where(seen, mins[:, 1], 0.0)
    feats[:, 6] = maxs[:, 0]
    feats[:, 7] = np.sqrt(np.maximum(sums[:, 4] / kk - mean_cn ** 2, 0.0))
    feats[:, 8] = sums[:, 5] / kk
    feats[:, 9] = maxs[:, 1]
    feats[~seen] = 0.0
    return feats, sums[:, 6] / kk


def view_features(scene: GaussianScene, cameras) -> np.ndarray:
    """The 10 view-alignment features (N, 10) float64 (see module doc)."""
    return view_statistics(scene, cameras)[0]


def edge_proxy(scene: GaussianScene, cameras, opacity: np.ndarray) -> np.ndarray:
    """e_i = o_i · (share of the visible views in which splat i is seen at a grazing angle)."""
    _, grazing = view_statistics(scene, cameras)
    return opacity * grazing
