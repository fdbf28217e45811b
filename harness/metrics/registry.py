"""The metrics a run can measure, with what tables need to show them: label, digits, direction.

    register_metric(MetricSpec("psnr", "PSNR", higher_is_better=True, digits=2, family="3dgs"))

``family`` groups metrics into sets a config can ask for by name (``metrics: [3dgs]`` expands to
every metric of that family). Cheap to import (no torch): configs and tables use it.
"""

from __future__ import annotations

from dataclasses import dataclass

from harness.core.registry import Registry


@dataclass(frozen=True)
class MetricSpec:
    name: str
    label: str
    higher_is_better: bool
    digits: int
    family: str
    doc: str = ""

    @property
    def heading(self) -> str:
        """Table heading with the direction arrow: ``PSNR (↑)``."""
        return f"{self.label} ({'↑' if self.higher_is_better else '↓'})"

    def better(self, a: float, b: float) -> bool:
        """Is value ``a`` better than ``b``?"""
        return a > b if self.higher_is_better else a < b


#: every metric :class:`harness.metrics.suite.MetricSuite` computes
METRICS: Registry[MetricSpec] = Registry("metric")
#: metrics against a view's captured photo (the paper's "against captured ground-truth images"):
#: ``gt_<name>`` for every registered ``<name>``, measured automatically where a view has a photo,
#: never asked for in a config; the others compare a pruned render with the unpruned render
GT_PREFIX = "gt_"
GT_FAMILY = "gt"


def register_metric(spec: MetricSpec) -> MetricSpec:
    """Register ``spec`` and its ``gt_`` twin: the same measure of a render against the captured
    photo of its view (:data:`GT_PREFIX`), measured wherever a view has a photo."""
    METRICS.add(spec.name, spec, same=lambda a, b: a == b)
    twin = GT_PREFIX + spec.name
    if not spec.name.startswith(GT_PREFIX) and twin not in METRICS.names():  # a photo metric of that name stays
        METRICS.add(twin, MetricSpec(twin, f"{spec.label} vs photo", spec.higher_is_better, spec.digits, GT_FAMILY,
                                     f"{spec.doc}; the render against the view's captured photo".lstrip("; ")))
    return spec


def get_metric(name: str) -> MetricSpec:
    return METRICS.get(name)


def expand(names) -> tuple[str, ...]:
    """Metric names with family names (``3dgs``) replaced by their members, duplicates dropped."""
    families = {}
    for m in METRICS:
        families.setdefault(m.family, []).append(m.name)
    out: list[str] = []
    for n in names:
        for m in families.get(n, [n]):
            if m not in out:
                out.append(m)
    return tuple(out)


register_metric(MetricSpec("psnr", "PSNR", True, 2, "3dgs", "dB on [0, 1]-clamped float images; +inf if identical"))
register_metric(MetricSpec("ssim", "SSIM", True, 3, "3dgs", "11×11 Gaussian σ 1.5, zero padding, data range 1"))
register_metric(MetricSpec("lpips", "LPIPS", False, 3, "3dgs", "LPIPS v0.1 VGG, inputs in [-1, 1]"))
register_metric(MetricSpec("gt_psnr_om", "OM-PSNR vs photo", True, 2, GT_FAMILY,
                           "PSNR against the photo over the pixels the unpruned render covers (accumulated alpha >= 0.5): "
                           "what the splats model, without a background they do not hold"))

# MPEG mpeg-gsc-metrics v3.0 (harness.metrics.mpeg): 8-bit renders, PSNRs capped at 999.99 dB, SSIM
# per Y/U/V plane; "_om": over the pixels either render occupies. Family `mpeg` is the tool's default
# mode, `mpeg-qmiv` its --computeQmiv=1 mode (integer BT.709, 4:1:1 weights).
for _sfx, _fam, _lab, _how in (("", "mpeg", "", "MPEG default: float BT.709, 1:1:1"),
                               ("_qmiv", "mpeg-qmiv", " (QMIV)", "QMIV: integer BT.709, 4:1:1")):
    register_metric(MetricSpec(f"rgb_psnr{_sfx}", f"RGB-PSNR{_lab}", True, 2, _fam, f"mpeg-gsc-metrics RGB PSNR, {_how}"))
    register_metric(MetricSpec(f"yuv_psnr{_sfx}", f"YUV-PSNR{_lab}", True, 2, _fam, f"mpeg-gsc-metrics YUV PSNR, {_how}"))
    register_metric(MetricSpec(f"yuv_ssim{_sfx}", f"YUV-SSIM{_lab}", True, 4, _fam, f"mpeg-gsc-metrics YUV SSIM, {_how}"))
    register_metric(MetricSpec(f"rgb_psnr_om{_sfx}", f"OM-RGB-PSNR{_lab}", True, 2, _fam, "occupancy-masked RGB-PSNR"))
    register_metric(MetricSpec(f"yuv_psnr_om{_sfx}", f"OM-YUV-PSNR{_lab}", True, 2, _fam, "occupancy-masked YUV-PSNR"))
    register_metric(MetricSpec(f"yuv_ssim_om{_sfx}", f"OM-YUV-SSIM{_lab}", True, 4, _fam, "occupancy-masked YUV-SSIM"))

# IV-SSIM (harness.metrics.ivssim): PMBB's xIVSSIM as mpeg-gsc-metrics calls it, block-averaged 8×8 SSIM
# after a ±2 px corresponding-pixel search and a global colour shift; the tool prints the same value in
# both modes, so only the `mpeg` family carries it.
register_metric(MetricSpec("rgb_ivssim", "RGB-IVSSIM", True, 4, "mpeg",
                           "mpeg-gsc-metrics IV-SSIM on R, G, B (1:1:1), PMBB xIVSSIM block-averaged"))
register_metric(MetricSpec("yuv_ivssim", "YUV-IVSSIM", True, 4, "mpeg",
                           "mpeg-gsc-metrics IV-SSIM on integer BT.709 YCbCr (4:1:1), PMBB xIVSSIM block-averaged"))


def mpeg_names(qmiv: bool = False) -> tuple[str, ...]:
    """The metric names of the mpeg (``qmiv=False``) or mpeg-qmiv family, registry order."""
    return tuple(m.name for m in METRICS if m.family == ("mpeg-qmiv" if qmiv else "mpeg"))


def requestable() -> list[str]:
    """Metric and family names a config or ``harness compare`` may ask for (photo metrics are not
    asked for: they come with the photos)."""
    own = [m for m in METRICS if m.family != GT_FAMILY]
    return [m.name for m in own] + sorted({m.family for m in own})


def is_gt(name: str) -> bool:
    """Is ``name`` a metric against the captured photo?"""
    return str(name).startswith(GT_PREFIX)


def gt_names(names) -> tuple[str, ...]:
    """The photo metrics measured beside ``names``: each one's ``gt_`` twin, and ``gt_psnr_om`` (PSNR
    over the pixels the unpruned render occupies) when PSNR is among them."""
    out = [GT_PREFIX + n for n in names if not is_gt(n)]
    return tuple(dict.fromkeys(out + (["gt_psnr_om"] if "psnr" in names else [])))


def needs_alpha(names) -> bool:
    """Do any of ``names`` need the renders' alpha (the occupancy-masked MPEG metrics)?"""
    om = {m.name for m in METRICS if m.family in ("mpeg", "mpeg-qmiv") and "_om" in m.name}
    return bool(om & set(names))
