"""A picture of where a set of cameras stands around a scene: two orthographic views of the splats
with every camera drawn on them, so anyone can see where a rig put its views.

Each panel projects the splat centres inside the content's bounding sphere (the weighted P95
distance from the weighted median centre, as the virtual rig uses) orthographically: the splats as
the mean colour of the centres falling on each pixel (opacity-weighted, sorted so nearer splats do
not matter: it is a density picture, not a render), the cameras as red dots with a white tick along
the direction they look. The panels are *top* (looking down ``up``) and *side* (looking along a
horizontal axis); without an ``up``, the content's own axes stand in: the axis of least spread of
the centres is drawn as up (the floor and a table top are the flattest parts of most captures),
which the panel titles say.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from harness.core.scene import GaussianScene, opacities
from harness.io.files import atomic_write_with

PANEL = 480
MARGIN = 24
SAMPLE = 300_000
SH_C0 = 0.28209479177387814


def _frame(points: np.ndarray, weights: np.ndarray, up) -> tuple[np.ndarray, str]:
    """Rows (right, forward, up) of the picture's frame, and how up was chosen."""
    if up is not None:
        u = np.asarray(up, np.float64) / np.linalg.norm(up)
        helper = np.array([1.0, 0.0, 0.0]) if abs(u[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        r = np.cross(helper, u)
        r /= np.linalg.norm(r)
        return np.stack([r, np.cross(u, r), u]), "up: the rig's support normal"
    c = points - np.average(points, axis=0, weights=weights)
    _, vecs = np.linalg.eigh((c * weights[:, None]).T @ c)
    u = vecs[:, 0]
    r = vecs[:, 2]
    return np.stack([r, np.cross(u, r), u]), "up: the content's axis of least spread"


def _panel(points, colours, weights, cams_xy, ticks_xy, lo, span):
    from PIL import Image, ImageDraw

    size = PANEL - 2 * MARGIN
    ij = np.clip(((points - lo) / span * (size - 1)).astype(np.int64), 0, size - 1)
    flat = ij[:, 1] * size + ij[:, 0]
    acc = np.zeros((size * size, 3))
    wsum = np.bincount(flat, weights=weights, minlength=size * size)
    for k in range(3):
        acc[:, k] = np.bincount(flat, weights=weights * colours[:, k], minlength=size * size)
    img = np.full((size * size, 3), 24.0)
    hit = wsum > 0
    img[hit] = 255.0 * acc[hit] / wsum[hit, None]
    img = img.reshape(size, size, 3)[::-1]  # image rows go down; the panel's second axis goes up
    canvas = Image.new("RGB", (PANEL, PANEL), (12, 12, 12))
    canvas.paste(Image.fromarray(img.clip(0, 255).astype(np.uint8)), (MARGIN, MARGIN))
    draw = ImageDraw.Draw(canvas)
    scale = (size - 1) / span
    to_px = lambda xy: (MARGIN + (xy[0] - lo[0]) * scale, MARGIN + (size - 1) - (xy[1] - lo[1]) * scale)
    for c, t in zip(cams_xy, ticks_xy):
        (x0, y0), (x1, y1) = to_px(c), to_px(t)
        draw.line([(x0, y0), (x1, y1)], fill=(255, 255, 255), width=1)
        draw.ellipse([x0 - 3, y0 - 3, x0 + 3, y0 + 3], fill=(230, 40, 40))
    return canvas, draw


def draw_rig(scene: GaussianScene, cameras, path: Path, *, center, radius: float, up=None, title: str = "") -> Path:
    """Write the two-panel PNG of ``cameras`` over ``scene`` to ``path`` (module docstring)."""
    from PIL import Image, ImageDraw

    means = scene.means.astype(np.float64)
    keep = np.all(np.isfinite(means), axis=1) & (np.linalg.norm(means - center, axis=1) <= radius)
    idx = np.flatnonzero(keep)
    if len(idx) > SAMPLE:
        idx = np.sort(np.random.default_rng(0).choice(idx, SAMPLE, replace=False))
    pts, w = means[idx], opacities(scene)[idx].astype(np.float64) + 1e-6
    colours = np.clip(0.5 + SH_C0 * scene.sh_dc[idx].astype(np.float64), 0.0, 1.0)
    frame, how = _frame(pts, w, up)
    eyes = np.array([c.center for c in cameras]).reshape(-1, 3)
    fwd = np.array([c.forward for c in cameras]).reshape(-1, 3)
    local = (pts - center) @ frame.T
    eye_l = (eyes - center) @ frame.T
    tick_l = eye_l + 0.08 * radius * (fwd @ frame.T)
    panels = []
    for axes, name in (((0, 1), "top (looking down up)"), ((0, 2), "side (up drawn up)")):
        both = np.concatenate([local[:, axes], eye_l[:, axes]]) if len(eye_l) else local[:, axes]
        lo, hi = both.min(0), both.max(0)
        span = float(max((hi - lo).max(), 1e-9)) * 1.04
        lo = (lo + hi) / 2 - span / 2
        canvas, draw = _panel(local[:, axes], colours, w, eye_l[:, axes], tick_l[:, axes], lo, span)
        draw.text((MARGIN, 4), name, fill=(230, 230, 230))
        panels.append(canvas)
    out = Image.new("RGB", (2 * PANEL, PANEL + 20), (12, 12, 12))
    for k, p in enumerate(panels):
        out.paste(p, (k * PANEL, 20))
    ImageDraw.Draw(out).text((MARGIN, 4), f"{title}  {len(cameras)} cameras (red, white tick: view direction); "
                             f"{how}", fill=(255, 255, 255))
    return atomic_write_with(Path(path), lambda tmp: out.save(tmp, format="PNG"))
