"""Scoring one pair of images with the registered metrics' CPU forms (:mod:`.registry`): each family's
joint computer once for its members, then each metric's own ``compute``, optionally on a reference's
side computed once per view (:func:`reference_sides`). LPIPS is left to :mod:`.suite` (features)."""

from __future__ import annotations

import numpy as np

from harness.metrics import registry as _registry


def _split(names) -> tuple[dict[str, list[str]], list]:
    """``names`` (LPIPS aside) as the members of each family with a joint computer and the metrics
    computed one by one (:mod:`.registry`)."""
    joint: dict[str, list[str]] = {}
    single = []
    for n in names:
        spec = _registry.METRICS.get(n)
        if n == "lpips":  # computed from features by the suite, not pair by pair
            continue
        if spec.compute is None and spec.family in _registry.FAMILIES:
            joint.setdefault(spec.family, []).append(n)
        else:
            single.append(spec)
    return joint, single


def reference_sides(ref: np.ndarray, names, device) -> dict:
    """What the metrics ``names`` compute from a reference alone (SSIM's window moments, the MPEG
    tool's 8-bit/YUV planes per mode: each metric's or family's ``prepare``), once for every image
    it is compared with; the values are those of scoring each pair from scratch, bit for bit."""
    joint, single = _split(names)
    sides = {fam: _registry.FAMILIES[fam].prepare(ref) for fam in joint if _registry.FAMILIES[fam].prepare}
    sides.update({s.name: s.prepare(ref, device) for s in single if s.prepare is not None})
    return sides


def pair_values(ref: np.ndarray, img: np.ndarray, names, *, device=None, mask=None, sides=None, raw=None) -> dict:
    """The metrics ``names`` (LPIPS aside) of one pair: each family's joint computer (on ``raw``
    ``(reference, test)`` when given: uint8 images scored as they are), then each metric's own
    ``compute`` (on ``sides``, the reference's :func:`reference_sides`, where it has one)."""
    sides = sides or {}
    joint, single = _split(names)
    out = {}
    for fam, members in joint.items():
        a, b = raw if raw is not None else (ref, img)
        out.update(_registry.FAMILIES[fam].compute(sides.get(fam, a), b, members, mask))
    for spec in single:
        kw = {k: v for k, v in (("device", device), ("mask", mask)) if spec.takes(k)}
        out[spec.name] = float(spec.compute(sides.get(spec.name, ref), img, **kw))
    return out
