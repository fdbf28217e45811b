"""Splat renderers behind one contract (gsplat-style one-function API)::

    renderer = get_renderer("gl")            # or "reference"
    image = renderer.render(scene, camera, background=(0, 0, 0))   # (H, W, 3) float32, linear, unclamped

``reference`` is the tile-based torch rasterizer (CPU or CUDA, differentiable, per-splat statistics);
``gl`` is the moderngl/EGL renderer (Mesa llvmpipe on the CPU, the GPU when present). Both implement
the classic 3DGS math described in DESIGN.md and must agree to ≥ 45 dB PSNR.
"""

from __future__ import annotations

RENDERERS = ("gl", "reference")


def get_renderer(name: str, device: str | None = None):
    """A renderer object with ``.name``, ``.render(scene, camera, background)`` and ``.close()``."""
    if name == "reference":
        from renderers.reference import ReferenceRenderer

        return ReferenceRenderer(device=device)
    if name == "gl":
        from renderers.gl import GLRenderer

        return GLRenderer()
    raise ValueError(f"unknown renderer {name!r}; known: {', '.join(RENDERERS)}")
