"""Splat renderers behind one contract (gsplat-style one-function API)::

    renderer = get_renderer("gl")            # or "reference"
    image = renderer.render(scene, camera, background=(0, 0, 0))   # (H, W, 3) float32, linear, unclamped

``reference`` is the tile-based torch rasterizer (CPU or CUDA, differentiable, per-splat statistics);
``gl`` is the moderngl/EGL renderer (Mesa llvmpipe on the CPU, the GPU when present). Both implement
the classic 3DGS math written out in :mod:`renderers.projection` and must agree to ≥ 45 dB PSNR.

A renderer declares what it can do beyond ``render`` in its class attribute ``capabilities``
(:func:`capabilities`): :data:`ALPHA` — ``render_with_alpha(scene, camera, background) -> (image,
alpha)`` in one pass; :data:`PACK` — ``pack(scene, camera) -> view`` and ``draw(view or
view.kept(mask), background, with_alpha)``: a view projected once and any subset of its splats drawn
from it, bit for bit the render of that subset; :data:`BATCH` — ``draw_many(views, background,
with_alpha)``: several packed views drawn before the first is read back (one wait for the device per
batch), each bit for bit its ``draw``; :data:`DEVICE_BATCH` — ``draw_many_on(views, device, background,
with_alpha) -> (images, alphas)``: the same batch as torch tensors on ``device``, copied there once
(:mod:`renderers.readback`). Callers ask :func:`capabilities`, never ``hasattr``.

Renderers are registered lazily (``"module:Class"``: nothing heavy is imported until one is made);
third parties add theirs through the ``harness.renderers`` entry-point group, whose modules call
:func:`register_renderer`.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass

from harness.core.registry import Registry


@dataclass(frozen=True)
class RendererSpec:
    name: str
    factory: str          # "module:Class"; Class(device=...) -> renderer
    label: str
    uses_device: bool     # honours a torch device (the GL renderer picks its own)
    differentiable: bool = False

    def make(self, device: str | None = None):
        module, _, attr = self.factory.partition(":")
        cls = getattr(importlib.import_module(module), attr)
        return cls(device=device) if self.uses_device else cls()


#: one-pass ``render_with_alpha`` (module docstring)
ALPHA = "alpha"
#: ``pack`` / ``draw``: a view projected once, its subsets drawn from it (module docstring)
PACK = "pack"
#: ``draw_many``: packed views drawn together, read back after the last draw (module docstring)
BATCH = "batch"
#: ``draw_many_on``: a batch of packed views as tensors on a torch device (module docstring)
DEVICE_BATCH = "device_batch"


def capabilities(renderer) -> frozenset[str]:
    """What ``renderer`` declares it can do beyond ``render`` (its class's ``capabilities``)."""
    return frozenset(getattr(type(renderer), "capabilities", ()))


RENDERERS: Registry[RendererSpec] = Registry("renderer", modules=(__name__,), group="harness.renderers")


def register_renderer(spec: RendererSpec) -> RendererSpec:
    RENDERERS.add(spec.name, spec, same=lambda a, b: a == b)
    return spec


def get_renderer(name: str, device: str | None = None):
    """A renderer object with ``.name``, ``.render(scene, camera, background)`` and ``.close()``."""
    try:
        spec = RENDERERS.get(name)
    except KeyError as err:
        raise ValueError(err.args[0]) from None
    return spec.make(device)


register_renderer(RendererSpec("gl", "renderers.gl:GLRenderer", "moderngl/EGL", uses_device=False))
register_renderer(RendererSpec("reference", "renderers.reference:ReferenceRenderer", "torch tile rasterizer",
                               uses_device=True, differentiable=True))
