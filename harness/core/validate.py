"""One check for every scene entering the harness, read from a file or built in memory: :func:`validate`.

A scene is valid when

* its arrays make one scene of N splats (:func:`harness.core.scene.shape_problem`) and every core
  array is float32 — what the readers and :meth:`GaussianScene.from_arrays` make; a scene whose
  arrays were replaced afterwards by arrays of another length or type is refused, never cast or
  broadcast behind the caller's back;
* every core value is finite: rows holding NaN or inf are an error naming their count, the first
  row and its array (``drop_nonfinite`` removes them instead and reports how many), since the
  pruners would score them as if they meant something (ten NaN opacities scored ≈ 0.5 and were kept)
  and a file written from them is one the readers refuse;
* no rotation quaternion has zero norm (the rotation is undefined).

The readers run it on what they read (:func:`harness.io.scenes.check_scene`), the Python API on
every scene it is handed (:mod:`harness.api.scenes`), so a scene is held to the same rules whichever
way it arrives. Errors are :class:`~harness.core.errors.InputError` naming ``source`` (a file, or the
API's argument ``scene``).
"""

from __future__ import annotations

import numpy as np

from harness.core.errors import InputError
from harness.core.scene import CORE, GaussianScene, shape_problem


def _first_row(mask: np.ndarray) -> int:
    return int(np.flatnonzero(mask)[0])


def nonfinite_rows(scene: GaussianScene) -> np.ndarray | None:
    """Bool (N,): rows with a NaN or inf in a core array; None when there are none (the common
    case costs one pass per array and no mask)."""
    if all(np.isfinite(getattr(scene, attr)).all() for attr in CORE):
        return None
    n = len(scene)
    bad = np.zeros(n, bool)
    for attr in CORE:
        bad |= ~np.isfinite(getattr(scene, attr).reshape(n, -1)).all(axis=1)
    return bad


def validate(scene, source="scene", *, drop_nonfinite: bool = False, hint: str = "") -> tuple[GaussianScene, int]:
    """``(scene, rows dropped)`` when ``scene`` is valid (module docstring), else InputError naming
    ``source``; ``hint`` ends the NaN message (how to drop such rows where ``source`` came from)."""
    if not isinstance(scene, GaussianScene):
        raise InputError(source, f"expected a GaussianScene, got {type(scene).__name__}")
    why = shape_problem(scene)
    if why:
        raise InputError(source, why)
    wrong = [a for a in CORE if getattr(scene, a).dtype != np.float32]
    if wrong:
        raise InputError(source, f"{wrong[0]} is {getattr(scene, wrong[0]).dtype}; a scene holds float32 arrays "
                                 "(GaussianScene.from_arrays casts)")
    dropped = 0
    bad = nonfinite_rows(scene)
    if bad is not None:
        dropped, n = int(bad.sum()), len(scene)
        if not drop_nonfinite:
            row = _first_row(bad)
            which = next(a for a in CORE if not np.isfinite(getattr(scene, a)[row]).all())
            raise InputError(source, f"{dropped} of {n} splats have NaN/inf values (first: row {row}, {which})"
                                     + (f"; {hint}" if hint else ""))
        scene = scene.subset(~bad)
    zero = ~(scene.quats != 0).any(axis=1)
    if zero.any():
        raise InputError(source, f"{int(zero.sum())} splats have a zero-norm rotation quaternion "
                                 f"(first: row {_first_row(zero)})")
    return scene, dropped
