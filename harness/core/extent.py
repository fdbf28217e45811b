"""How far from the origin the render pipeline can take a scene: every coordinate within
±:data:`COORD_MAX` (10¹²), for splat centres as for camera centres.

The renderers project in float32 (:mod:`renderers.projection`), whose squares overflow at about
1.8·10¹⁹. Measured on grape-small with its lengths (centres, splat sizes and cameras alike) scaled
by 10ᵏ: renders at k = 6 … 19 equal the unscaled ones to 89–136 dB; at k = 20 they fall to 29 dB.
Before cameras were checked, the synthetic rigs turned scenes at 10¹⁷ and beyond into NaN cameras,
black renders and PSNR +inf read as perfect. A camera file already refused centres beyond 10¹²;
the same bound now holds for every :class:`~harness.core.cameras.Camera` made and for every scene a
command renders, seven orders of magnitude inside float32's range.

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


def largest_coordinate(scene) -> float:
    """The largest absolute coordinate of the scene's splat centres (0 for no splats; inf when one
    is not finite)."""
    if len(scene) == 0:
        return 0.0
    with np.errstate(invalid="ignore"):
        value = float(np.abs(scene.means).max())
    return value if value == value else float("inf")


def extent_problem(scene) -> str | None:
    """Why the render pipeline cannot hold ``scene`` (module docstring), or None."""
    far = largest_coordinate(scene)
    if far <= COORD_MAX:
        return None
    beyond = ~(np.abs(scene.means) <= COORD_MAX).all(axis=1)
    first = int(np.flatnonzero(beyond)[0])
    return (f"{int(beyond.sum())} of {len(scene)} splats lie beyond ±{COORD_MAX:g} (first: row {first}; the farthest "
            f"at {far:.3g}): the float32 render pipeline and its cameras hold coordinates up to {COORD_MAX:g}; "
            "remove those splats or scale the scene down")


def check_extent(scene, source) -> None:
    """InputError naming ``source`` when the render pipeline cannot hold ``scene``."""
    why = extent_problem(scene)
    if why:
        raise InputError(source, why)
