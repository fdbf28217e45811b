"""The built-in metrics, each registered once with everything the tools need (:mod:`.registry`).

* family ``3dgs``: PSNR (dB on [0, 1]-clamped float images, +inf if identical), SSIM (3DGS
  convention: 11×11 Gaussian σ 1.5, zero padding) and LPIPS v0.1 VGG — :mod:`.psnr`, :mod:`.ssim`,
  :mod:`.lpips_vgg`;
* families ``mpeg`` and ``mpeg-qmiv``: MPEG mpeg-gsc-metrics v3.0 (:mod:`.mpeg`), computed together per
  mode from one 8-bit/YUV reference side (:class:`.mpeg.ToolReference`): RGB-/YUV-PSNR capped at
  999.99 dB, YUV-SSIM per Y/U/V plane, their occupancy-masked (``_om``) variants over the pixels
  either render occupies, and (``mpeg`` only: the tool prints the same value in both modes) IV-SSIM;
* ``gt_psnr_om``: PSNR against the photo over the pixels the unpruned render covers.

Heavy libraries (torch) are imported inside the compute functions, so registering costs nothing.
"""

from __future__ import annotations

import math

from harness.metrics.registry import GT_FAMILY, register_family, register_metric

INF = math.inf


# --------------------------------------------------------------------------- 3dgs
def psnr_pair(reference, test) -> float:
    from harness.metrics.psnr import mse, psnr_from_mse

    return psnr_from_mse(mse(reference, test))


def ssim_reference(reference, device):
    """SSIM's side of a reference (window moments), once per view (:class:`.ssim.SsimReference`)."""
    from harness.metrics.ssim import SsimReference

    return SsimReference(reference[None], device=device)


def ssim_pair(reference, test, *, device=None) -> float:
    """``reference``: an image or its :func:`ssim_reference`."""
    from harness.metrics.ssim import SsimReference, ssim_batch

    first = reference if isinstance(reference, SsimReference) else reference[None]
    return float(ssim_batch(first, test[None], border="zero", device=device)[0])


def lpips_pair(reference, test, *, device=None) -> float:
    from harness.metrics.suite import default_lpips

    if device is None:
        return default_lpips()(reference, test)
    from harness.metrics.lpips_vgg import LpipsVGG

    return LpipsVGG(device=device)(reference, test)


def lpips_check() -> None:
    """LPIPS-VGG weights not fetched -> InputError (before any work)."""
    from harness.core.errors import InputError
    from harness.metrics.lpips_weights import FETCH_HINT, weights_path

    if not weights_path().is_file():
        raise InputError(weights_path(), f"LPIPS-VGG backbone weights are missing; {FETCH_HINT}")


register_metric("psnr", compute=psnr_pair, higher_is_better=True, valid_range=(0, INF), inf_if_identical=True,
                unit="dB", cost="psnr", family="3dgs", label="PSNR", digits=2, tolerance=0.5,
                doc="dB on [0, 1]-clamped float images; +inf if identical")
register_metric("ssim", compute=ssim_pair, prepare=ssim_reference, higher_is_better=True, valid_range=(-1, 1),
                cost="ssim", family="3dgs", label="SSIM", digits=3, tolerance=0.005,
                doc="11×11 Gaussian σ 1.5, zero padding, data range 1")
register_metric("lpips", compute=lpips_pair, check=lpips_check, higher_is_better=False, valid_range=(0, INF),
                cost="lpips", family="3dgs", label="LPIPS", digits=3, tolerance=0.005,
                doc="LPIPS v0.1 VGG, inputs in [-1, 1]")
register_metric("gt_psnr_om", higher_is_better=True, valid_range=(0, INF), inf_if_identical=True, unit="dB",
                cost="psnr", family=GT_FAMILY, label="OM-PSNR vs photo", digits=2, masks="gt_psnr",
                with_metric="psnr",
                doc="PSNR against the photo over the pixels the unpruned render covers (accumulated alpha >= 0.5): "
                    "what the splats model, without a background they do not hold")


# --------------------------------------------------------------------------- MPEG
def _tool_family(qmiv: bool):
    """The joint computer of the mpeg (``qmiv=False``) or mpeg-qmiv family: one call of
    :func:`.mpeg.tool_metrics` for every member asked for (:func:`.mpeg_members.tool_request`)."""

    def prepare(reference):
        from harness.metrics.mpeg import ToolReference

        return ToolReference(reference, qmiv=qmiv)

    def compute(reference, test, names, mask=None) -> dict:
        import numpy as np

        from harness.core.errors import InputError
        from harness.metrics.mpeg import tool_metrics
        from harness.metrics.mpeg_members import size_problem, tool_members, tool_request

        why = size_problem(*np.shape(test)[:2], names, qmiv)
        if why:
            raise InputError("images", why)
        base, flags = tool_request(names, qmiv)
        return tool_members(tool_metrics(reference, test, mask, qmiv=qmiv, **flags), base, flags["om"])

    return compute, prepare


for _qmiv, _fam, _sfx, _lab, _how in ((False, "mpeg", "", "", "MPEG default: float BT.709, 1:1:1"),
                                      (True, "mpeg-qmiv", "_qmiv", " (QMIV)", "QMIV: integer BT.709, 4:1:1")):
    _compute, _prepare = _tool_family(_qmiv)
    register_family(_fam, compute=_compute, prepare=_prepare)
    _db = dict(higher_is_better=True, valid_range=(0, INF), unit="dB", cost="psnr", family=_fam, digits=2)
    _ss = dict(higher_is_better=True, valid_range=(-1, 1), cost="ssim", family=_fam, digits=4)
    register_metric(f"rgb_psnr{_sfx}", label=f"RGB-PSNR{_lab}", doc=f"mpeg-gsc-metrics RGB PSNR, {_how}", **_db)
    register_metric(f"yuv_psnr{_sfx}", label=f"YUV-PSNR{_lab}", doc=f"mpeg-gsc-metrics YUV PSNR, {_how}", **_db)
    register_metric(f"yuv_ssim{_sfx}", label=f"YUV-SSIM{_lab}", doc=f"mpeg-gsc-metrics YUV SSIM, {_how}", **_ss)
    register_metric(f"rgb_psnr_om{_sfx}", label=f"OM-RGB-PSNR{_lab}", doc="occupancy-masked RGB-PSNR",
                    needs_alpha=True, masks=f"rgb_psnr{_sfx}", **_db)
    register_metric(f"yuv_psnr_om{_sfx}", label=f"OM-YUV-PSNR{_lab}", doc="occupancy-masked YUV-PSNR",
                    needs_alpha=True, masks=f"yuv_psnr{_sfx}", **_db)
    register_metric(f"yuv_ssim_om{_sfx}", label=f"OM-YUV-SSIM{_lab}", doc="occupancy-masked YUV-SSIM",
                    needs_alpha=True, masks=f"yuv_ssim{_sfx}", **_ss)

# IV-SSIM (harness.metrics.ivssim): PMBB's xIVSSIM as mpeg-gsc-metrics calls it, block-averaged 8×8 SSIM
# after a ±2 px corresponding-pixel search and a global colour shift; the tool prints the same value in
# both modes, so only the `mpeg` family carries it.
register_metric("rgb_ivssim", label="RGB-IVSSIM", higher_is_better=True, valid_range=(-1, 1), cost="ssim",
                family="mpeg", digits=4,
                doc="mpeg-gsc-metrics IV-SSIM on R, G, B (1:1:1), PMBB xIVSSIM block-averaged")
register_metric("yuv_ivssim", label="YUV-IVSSIM", higher_is_better=True, valid_range=(-1, 1), cost="ssim",
                family="mpeg", digits=4,
                doc="mpeg-gsc-metrics IV-SSIM on integer BT.709 YCbCr (4:1:1), PMBB xIVSSIM block-averaged")
