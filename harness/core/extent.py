"""How far from the origin the render pipeline can take a scene: every coordinate within
±:data:`COORD_MAX` (10¹²), for splat centres as for camera centres.

The renderers project in float32 (:mod:`renderers.projection`), whose squares overflow at about
1.8·10¹⁹. Measured on grape-small with its lengths (centres, splat sizes and cameras alike) scaled
by 10ᵏ: renders at k = 6 … 19 equal the unscaled ones to 89–136 dB; at k = 20 they fall to 29 dB.
Before cameras were checked, the synthetic rigs turned scenes at 10¹⁷ and beyond into NaN cameras,
black renders and PSNR +inf read as perfect. A camera file already refused centres beyond 10¹²;
the same bound now holds for every :class:`~harness.core.cameras.Camera` made and for every scene a
command renders, seven orders of magnitude inside float32's range.

The other way to lose precision is a scene far from the origin for its size: float32 spaces its
numbers 2⁻²³ of their magnitude apart, so the centres of a unit scene moved 10⁷ away all round to a
few points and its renders are empty. A scene whose bulk float32 resolves more coarsely than
:data:`MAX_BLUR` of its radius is refused too (a few far floaters do not count: the bulk is the
median centre and the 90th percentile radius).

"A scene whose extent makes the float32 pipeline lose precision … is refused at load with one line
saying why, or re-centred/scaled exactly": refused. Rescaling by a power of two is exact for the
centres but not for the log-scales (``ŝ + k·ln 2`` rounds), and a pruned file must keep its input's
bytes, so the harness does not move a scene; it says which splats lie too far. Where it is checked:
wherever a scene enters rendering — ``harness render``, ``score``, ``diagnose``, the API's
``render``/``cameras``/``evaluate`` and a study's load stage (an error of that scene) — but not
``info``, ``convert`` or camera-free ``prune``, which do not render (a file with one splat at 10³⁰
still converts, with the writers' own warning).
"""

from __future__ import annotations

import numpy as np

from harness.core.cameras import COORD_MAX
from harness.core.errors import InputError

#: the coarsest float32 resolution of a scene's bulk the pipeline renders, as a share of its radius
#: (:func:`blur`). Measured on grape-small (radius 0.21) moved by k along every axis, cameras with
#: it, PSNR to the unmoved renders (128 px, gl): k = 10² 81 dB, 10³ 67–69 dB (blur 0.03 %), 10⁴
#: 45–52 dB (0.47 %: refused), 10⁵ 29–31 dB, 10⁶ 14–18 dB, 10⁷ 13 dB (centres rounded to a few points)
MAX_BLUR = 1e-3


def largest_coordinate(scene) -> float:
    """The largest absolute coordinate of the scene's splat centres (0 for no splats; inf when one
    is not finite)."""
    if len(scene) == 0:
        return 0.0
    with np.errstate(invalid="ignore"):
        value = float(np.abs(scene.means).max())
    return value if value == value else float("inf")


def blur(scene) -> float:
    """How coarsely float32 resolves the bulk of ``scene``: the spacing of float32 numbers at its
    centre's farthest coordinate plus its radius, as a share of the radius (centre: the median of a
    sample of up to 100,000 splat centres; radius: their 90th percentile distance from it, at least
    their median splat size ``exp(max log-scale)``, so a scene whose centres all rounded to one point
    is not read as resolved; 0 for no splats or a radius of 0)."""
    step = max(1, len(scene) // 100_000)
    pts = np.asarray(scene.means[::step], np.float64)
    if len(pts) == 0:
        return 0.0
    centre = np.median(pts, axis=0)
    with np.errstate(over="ignore", invalid="ignore"):
        size = float(np.nanmedian(np.exp(np.asarray(scene.scales_log[::step], np.float64).max(axis=1))))
    radius = max(float(np.percentile(np.linalg.norm(pts - centre, axis=1), 90)), size if size == size else 0.0)
    far = float(np.abs(centre).max()) + radius
    return float(np.spacing(np.float32(far))) / radius if 0 < radius and np.isfinite(far) else 0.0


def extent_problem(scene) -> str | None:
    """Why the render pipeline cannot hold ``scene`` (module docstring), or None."""
    far = largest_coordinate(scene)
    if far > COORD_MAX:
        beyond = ~(np.abs(scene.means) <= COORD_MAX).all(axis=1)
        first = int(np.flatnonzero(beyond)[0])
        return (f"{int(beyond.sum())} of {len(scene)} splats lie beyond ±{COORD_MAX:g} (first: row {first}; the "
                f"farthest at {far:.3g}): the float32 render pipeline and its cameras hold coordinates up to "
                f"{COORD_MAX:g}; remove those splats or scale the scene down")
    share = blur(scene)
    if share > MAX_BLUR:
        return (f"its splats sit so far from the origin for their size that float32's steps there are "
                f"{100 * share:.2g} % of its radius (at most {100 * MAX_BLUR:g} % renders faithfully; beyond, renders "
                "are blurred or empty); move the scene near the origin")
    return None


def check_extent(scene, source) -> None:
    """InputError naming ``source`` when the render pipeline cannot hold ``scene``."""
    why = extent_problem(scene)
    if why:
        raise InputError(source, why)
