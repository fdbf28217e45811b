"""The members of the mpeg and mpeg-qmiv metric families and the values of the tool they read:
what one call of :func:`.mpeg.tool_metrics` (or its torch form,
:func:`.mpeg_torch.tool_metrics_batch`) must compute for the members asked for, and their values
from its result."""

from __future__ import annotations

#: what part of the tool's computation a member needs beyond its PSNR sums (mpeg.tool_metrics flags)
_TOOL_PART = {"yuv_ssim": "ssim", "yuv_ssim_om": "ssim", "rgb_ivssim": "iv", "yuv_ivssim": "iv"}


def tool_request(names, qmiv: bool) -> tuple[dict, dict]:
    """What a call of the tool computes for the members ``names`` of the mpeg (``qmiv=False``) or
    mpeg-qmiv family: (member -> the tool's key, the :func:`.mpeg.tool_metrics` flags)."""
    from harness.metrics.registry import METRICS

    suffix = "_qmiv" if qmiv else ""
    base = {n: n[: len(n) - len(suffix)] for n in names}
    parts = {_TOOL_PART.get(b) for b in base.values()}
    om = any(METRICS.get(n).needs_alpha for n in names)
    return base, {"ssim": "ssim" in parts, "om": om, "iv": "iv" in parts}


def tool_members(r: dict, base: dict, om: bool) -> dict:
    """The members' values from one :func:`.mpeg.tool_metrics` result, plus ``occupancy`` (%) with an OM one."""
    out = {n: float(r[b]) for n, b in base.items()}
    if om:
        out["occupancy"] = float(r["occupancy"])
    return out


#: the smallest image side each part of the tool is defined on: IV-SSIM sums 8×8 blocks (none fit a
#: smaller image: NaN), the YUV-SSIM padding reads 5 columns beside the edge (the tool reads out of
#: bounds on narrower images: an IndexError here); the PSNRs take any size
MIN_SIDE = {"iv": 8, "ssim": 6}


def size_problem(height: int, width: int, names, qmiv: bool) -> str | None:
    """Why images of ``width`` × ``height`` have no value for the members ``names``, or None."""
    base, flags = tool_request(names, qmiv)
    for part, side in MIN_SIDE.items():
        if flags[part] and min(height, width) < side:
            which = ", ".join(n for n, b in base.items() if _TOOL_PART.get(b) == part)
            what = "IV-SSIM's 8x8 blocks" if part == "iv" else "the tool's 11x11 SSIM window"
            return f"{width}x{height} pixels is too small for {which} ({what}: at least {side} px per side)"
    return None
