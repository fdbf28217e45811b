"""Image metrics: PSNR, SSIM (3DGS convention), LPIPS v0.1 VGG, the mpeg-gsc-metrics set, and their registry.

* :mod:`.registry` — :func:`register_metric`: one registration per metric with everything the tools
  need (compute, direction, valid range, cost, alpha, unit, family), a ``gt_`` twin per metric, and
  the ``harness.metrics`` entry-point group for third-party metrics (cheap to import: no torch);
* :mod:`.builtin` — the built-in registrations;
* :mod:`.suite` — :func:`compare_images` (one pair) and :class:`MetricSuite` (many images per view);
* :mod:`.psnr`, :mod:`.ssim`, :mod:`.lpips_vgg`, :mod:`.mpeg` — the definitions.

Imports harness.core and harness.io only.
"""

from harness.metrics.registry import register_family, register_metric

__all__ = ["register_family", "register_metric"]
