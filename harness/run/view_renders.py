"""A view's renders, whole and pruned, for a view task (:func:`harness.run.tasks.run_view`): packed
once and filtered per keep mask where the renderer packs views, drawn as a batch where it draws
batches, a subset scene rendered in full otherwise."""

from __future__ import annotations

import time

import numpy as np

from harness.core.cameras import Camera
from renderers import ALPHA, BATCH, DEVICE_BATCH, PACK, capabilities


def render_alpha(renderer, scene, cam: Camera, background) -> tuple[np.ndarray, np.ndarray]:
    """(image, alpha) of a render; a renderer without the :data:`renderers.ALPHA` capability renders
    twice (black and white backgrounds: image(bg) = C + (1 − alpha)·bg)."""
    if ALPHA in capabilities(renderer):
        img, alpha = renderer.render_with_alpha(scene, cam, background=background)
        return np.asarray(img, np.float32), np.asarray(alpha, np.float32)
    img = np.asarray(renderer.render(scene, cam, background=background), np.float32)
    black = np.asarray(renderer.render(scene, cam, background=(0.0, 0.0, 0.0)), np.float64)
    white = np.asarray(renderer.render(scene, cam, background=(1.0, 1.0, 1.0)), np.float64)
    return img, (1.0 - (white - black).mean(axis=2)).astype(np.float32)


class ViewRenders:
    """Renders of one view of a scene, whole or pruned: ``self(keep)`` -> ``(image, alpha or None)``
    (``keep``: bool per splat, None = every splat; alpha when ``with_alpha``).

    A renderer that packs views (the :data:`renderers.PACK` capability: the GL renderer) projects, sorts and packs the
    scene once, on first use, and draws each pruned set as its splats filtered from that packing,
    bit for bit the render of ``scene.subset(keep)`` (:meth:`renderers.gl.PackedView.kept`); others
    render every subset. ``pack_s``: seconds the packing took (0 before :meth:`prepare`).

    ``device``: the study's torch device. On CUDA, with a renderer that reads a batch into one
    tensor (:data:`renderers.DEVICE_BATCH`), :meth:`many_on_device` hands the batch to the metrics
    there (:meth:`frames_on_device`); elsewhere the frames are host arrays, as they always were.
    """

    def __init__(self, renderer, scene, cam: Camera, background, with_alpha: bool, device: str | None = None):
        self.renderer, self.scene, self.cam = renderer, scene, cam
        self.background, self.with_alpha, self.device = background, with_alpha, device
        self._packed = None
        self.pack_s = 0.0

    def prepare(self) -> None:
        """Pack the view now (when the renderer packs views; once)."""
        r = self.renderer
        if self._packed is None and PACK in capabilities(r):
            t0 = time.perf_counter()
            self._packed = r.pack(self.scene, self.cam)
            self.pack_s = time.perf_counter() - t0

    def __call__(self, keep: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | None]:
        r = self.renderer
        self.prepare()
        if self._packed is not None:
            return self._arrays(r.draw(self._packed if keep is None else self._packed.kept(keep), self.background,
                                       with_alpha=self.with_alpha))
        return self._whole(keep)

    def many(self, keeps: list[np.ndarray]) -> list[tuple[np.ndarray, np.ndarray | None]]:
        """``[self(keep) for keep in keeps]``, bit for bit; a renderer that draws batches
        (:data:`renderers.BATCH`) reads them back once, after the last draw."""
        r = self.renderer
        self.prepare()
        if self._packed is None or len(keeps) <= 1 or BATCH not in capabilities(r):
            return [self(keep) for keep in keeps]
        outs = r.draw_many([self._packed.kept(keep) for keep in keeps], self.background, with_alpha=self.with_alpha)
        return [self._arrays(out) for out in outs]

    def frames_on_device(self) -> bool:
        """Whether :meth:`many_on_device` applies: the renderer packs views and reads a batch into a
        tensor, and the device is CUDA (:func:`renderers.readback.on_cuda`; the CPU is answered
        without importing torch)."""
        caps = capabilities(self.renderer)
        if self.device in (None, "cpu") or PACK not in caps or DEVICE_BATCH not in caps:
            return False
        from renderers.readback import on_cuda

        return on_cuda(self.device)

    def many_on_device(self, keeps: list[np.ndarray]):
        """``(images (N, H, W, 3), alphas (N, H, W) or None)``, torch tensors on the device, of the
        pruned sets ``keeps``: each image bit for bit ``self(keep)``, the batch copied there once."""
        self.prepare()
        views = [self._packed.kept(keep) for keep in keeps]
        return self.renderer.draw_many_on(views, self.device, self.background, with_alpha=self.with_alpha)

    def _arrays(self, out) -> tuple[np.ndarray, np.ndarray | None]:
        img, alpha = out if self.with_alpha else (out, None)
        return np.asarray(img, np.float32), None if alpha is None else np.asarray(alpha, np.float32)

    def _whole(self, keep: np.ndarray | None) -> tuple[np.ndarray, np.ndarray | None]:
        """A renderer without packing: the subset scene rendered in full."""
        r = self.renderer
        scene = self.scene if keep is None else self.scene.subset(keep)
        if self.with_alpha:
            return render_alpha(r, scene, self.cam, self.background)
        return np.asarray(r.render(scene, self.cam, background=self.background), dtype=np.float32), None


def stacked(frames: list):
    """Frames of a batch as the metrics take them: device tensors (:meth:`ViewRenders.many_on_device`)
    stacked into one ``(N, ...)`` tensor, host arrays left a list."""
    if frames and frames[0] is not None and not isinstance(frames[0], np.ndarray):
        import torch

        return torch.stack(frames)
    return frames


def host_array(frame) -> np.ndarray:
    """A frame as a host array (a device tensor copied back: for its PNG)."""
    return frame if isinstance(frame, np.ndarray) else frame.cpu().numpy()
