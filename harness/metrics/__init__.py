"""Image metrics: PSNR, SSIM (3DGS convention), LPIPS v0.1 VGG, and their registry.

* :mod:`.registry` — the metric names with their table labels and which direction is better
  (cheap to import: configs and tables use it without loading torch);
* :mod:`.suite` — :func:`compare_images` (one pair) and :class:`MetricSuite` (many images per view);
* :mod:`.psnr`, :mod:`.ssim`, :mod:`.lpips_vgg` — the definitions.

Imports harness.core and harness.io only.
"""
