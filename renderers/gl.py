"""moderngl/EGL splat renderer: classic 3DGS compositing with instanced triangles and GL blending.

Pipeline per view (the projection math lives once, in :mod:`renderers.projection`):

1. ``project_arrays(scene, camera)`` → :class:`~renderers.projection.Projected` (visible splats:
   2D means, conics, depths, radii, colours, opacities): numpy on the CPU, without importing torch;
   on a CUDA device (a machine with an NVIDIA GPU, or ``device="cuda"``) ``project_gaussians`` in torch.
2. Splats with ``o < 1/255`` are dropped (their α = min(0.99, o·g) with g ≤ 1 can never pass the
   1/255 test, so this is exact). The rest are sorted front to back by view depth (stable
   argsort, ties by projection order) into a :class:`PackedView` (:meth:`GLRenderer.pack`),
   uploaded as one interleaved instance buffer. A view packed once serves every pruned set of its
   scene: ``view.kept(keep)`` is bit for bit what ``scene.subset(keep)`` packs to (a splat's record
   depends on that splat alone, see :mod:`renderers.projection`; the sort is stable), at the cost of
   one row filter instead of a projection, sort and pack (0.13-0.42 CPU-s per image at 384 px).
3. One instanced draw, one triangle per splat, covering the ellipse ``dᵀ Q d ≤ K``,
   ``K = 2·ln(255·o)``, i.e. exactly where ``o·exp(−½ dᵀQd) ≥ 1/255``: pixels outside it are
   discarded by the α test anyway, so the tight triangle changes no pixel (a 0.1 % + 0.01 px margin
   covers float rounding). The triangle is the smaller (by area) of (a) the one circumscribing the
   ellipse (an equilateral triangle around the unit circle mapped by the conic's eigen-axes) and
   (b) a right triangle around the ellipse's axis-aligned box clipped to the footprint (below) and
   to the image (huge splats). Measured on llvmpipe (bonsai-7k, 570k splats in view): one triangle per
   splat costs ~15 % less than a two-triangle quad (half the set-up, no 4×4 blocks shaded twice
   along the diagonal) despite ~30 % more area; fragment work dominates, the shader math does not
   (a shader that discards at once costs the same).
4. The fragment shader evaluates, for pixel ``p`` (3DGS frame, see below) and ``d = p − mean``::

       power = −½ (a·dx² + c·dy²) − b·dx·dy          (discard if power > 0)
       α     = min(0.99, o·exp(power))                (discard if α < 1/255)
       out   = (c·α, α)                               (colour premultiplied)

   and first discards pixels outside the splat's footprint, as the reference rasterizer's
   ``footprint`` option: ``"box"`` (default): pixel (i, j) is considered iff ``|dx| ≤ r`` and
   ``|dy| ≤ r``; ``"tile"`` (graphdeco): every pixel of the 16-px tiles of ``getRect``
   (``[⌊(m − r)/16⌋, ⌊(m + r + 15)/16⌋)`` clamped to the grid), which also paints faint pixels just
   beyond the radius of splats with o > e^4.5/255 ≈ 0.35. Either way the triangle bounds the work.
5. Front-to-back "under" compositing with the transmittance itself kept in the alpha channel of an
   RGBA32F target cleared to (0, 0, 0, 1): blend func ``rgb: (DST_ALPHA, ONE)``,
   ``alpha: (ZERO, ONE_MINUS_SRC_ALPHA)``, i.e. for each fragment in primitive (= depth) order::

       C ← C + (c·α)·T        T ← T·(1 − α)

   which is the reference recursion operation for operation (T is not re-derived as 1 − Σ).
   GL applies blending in primitive order, so the result is the depth-sorted sum
   ``C = Σ cᵢ αᵢ Tᵢ`` and the final image is ``C + T·bg`` (done on the CPU in float32).
   Float32 blending is unclamped (checked on llvmpipe: values > 1 and < 0 survive).

**Difference from graphdeco:** GL blending cannot stop a pixel once ``T·(1 − α) < 1e-4`` (that
needs to read the destination in the shader), so every splat is composited; the reference
rasterizer's ``early_stop=False`` setting matches this renderer. graphdeco also leaves out the
splat that crosses the threshold, so against ``early_stop=True`` a pixel differs by the colour
behind the stop, at most ``T_before·max c`` with ``T_before < 1e-4 / (1 − 0.99) = 1e-2`` (in
practice about 1e-4).

**Agreement with the reference** (same footprint, ``early_stop=False``): float32 rounding (~1e-6)
except where a splat's α lies within a few ulps of 1/255: GLSL's ``exp`` and torch's differ in the
last bits (numpy's too), so the cut may flip and that pixel differs by about ``c/255`` (seen: 0–2
pixels per 1024-px view of the real scenes, PSNR ≥ 110 dB).

**Pixel centres:** pixel (i, j) of the image is centred at ``(i, j)`` in the ``means2d`` frame
(graphdeco: ``pixf = (x, y)``; ``means2d = fx·x/z + cx − 0.5``). GL puts the fragment centre of
window pixel (i, j) at ``gl_FragCoord.xy = (i + 0.5, j + 0.5)``, so the shader uses
``p = gl_FragCoord.xy − 0.5 + tile_origin``. Window row j is image row j: means2d y (down) is used
as GL window y (up) without a flip, and ``glReadPixels`` returns rows bottom-up = image rows
top-down, so the read-back needs no flip either.

**Tiling:** images larger than ``GL_MAX_VIEWPORT_DIMS`` / ``GL_MAX_RENDERBUFFER_SIZE`` /
:data:`DEFAULT_MAX_TILE` (or the ``max_tile`` argument) are rendered tile by tile into one
framebuffer of tile size, with the tile origin as a uniform; every tile redraws all instances (the
GL clipper drops the others) and is composited with the background straight into the output.
"""

from __future__ import annotations

import logging
import math
from typing import Self

import numpy as np

from renderers.gl_shaders import FRAGMENT_SHADER, VERTEX_SHADER
from renderers.gl_wait import wait_without_gil
from renderers.packing import PackedView, pack_instances

log = logging.getLogger(__name__)



def _load_triton_first() -> None:
    """Import triton (when installed) before Mesa loads its LLVM into the process.

    Measured here: creating an llvmpipe EGL context and *then* importing triton (which
    ``torch.compile`` does, e.g. the reference rasterizer's compiled step) segfaults while loading
    ``libtriton.so``; in the other order both work. So the GL renderer loads triton first.
    """
    try:
        import triton  # noqa: F401
    except ImportError:  # not installed: nothing can clash with it later
        return
    except Exception as err:  # noqa: BLE001 - a broken triton install is torch's business, not ours
        log.debug("triton import failed before creating the GL context: %s", err)


FOOTPRINTS = ("box", "tile")

#: largest framebuffer side by default: a 4096² RGBA32F target is 256 MiB (the GL limit, often
#: 16384, would be 4 GiB); larger images are tiled.
DEFAULT_MAX_TILE = 4096


class GLUnavailable(RuntimeError):
    """No EGL OpenGL 3.3 context could be created on this machine."""


def tiles(width: int, height: int, max_tile: int):
    """Tile rectangles ``(x0, y0, w, h)`` covering a ``width × height`` image, row-major."""
    for y0 in range(0, height, max_tile):
        for x0 in range(0, width, max_tile):
            yield x0, y0, min(max_tile, width - x0), min(max_tile, height - y0)


class GLRenderer:
    """Classic 3DGS rendering on OpenGL (EGL, headless): llvmpipe on the CPU, a GPU when present.

    One context per renderer, created on first use and kept until :meth:`close`; every GL call runs
    with that context made current, so several renderers can share a process. ``max_tile`` caps the
    framebuffer side (default: the GL limits and :data:`DEFAULT_MAX_TILE`); tests use it to force
    tiling. ``device``: where splats are projected — None: numpy on the CPU, or torch on CUDA when
    the machine has an NVIDIA GPU (:meth:`projection_device`); ``"cpu"`` numpy; any other torch
    device torch there. ``footprint``: ``"box"`` or ``"tile"``, see the module docstring.
    ``preload_triton`` (default True, see :func:`_load_triton_first`): a one-shot process that never
    calls ``torch.compile`` (``harness render``) sets it False before the first draw.
    """

    #: what it can do beyond ``render`` (:func:`renderers.capabilities`)
    capabilities = frozenset({"alpha", "pack", "batch", "device_batch"})

    name = "gl"

    def __init__(self, max_tile: int | None = None, device=None, footprint: str = "box"):
        if footprint not in FOOTPRINTS:
            raise ValueError(f"footprint must be one of {FOOTPRINTS}, got {footprint!r}")
        self.footprint = footprint
        self.device = device
        self.preload_triton = True
        self._max_tile_arg = max_tile
        self.ctx = None
        #: per slot (a view of a batch in flight): its framebuffer and renderbuffer, all of one size
        self._targets: list[tuple] = []
        self._target_size = None
        #: per slot: its instance buffer and vertex array
        self._slots: list[tuple] = []

    # ------------------------------------------------------------------ context
    def _ensure_context(self) -> None:
        if self.ctx is not None:
            return
        import moderngl

        if self.preload_triton:
            _load_triton_first()
        try:
            ctx = moderngl.create_standalone_context(backend="egl", require=330)
        except Exception as exc:  # glcontext raises plain Exception subclasses
            raise GLUnavailable(f"cannot create an EGL OpenGL 3.3 context: {exc}") from exc
        self.ctx = ctx
        self._moderngl = moderngl
        with ctx:
            self._prog = ctx.program(vertex_shader=VERTEX_SHADER, fragment_shader=FRAGMENT_SHADER)
            corners = np.array([0.0, 2.0, -math.sqrt(3.0), -1.0, math.sqrt(3.0), -1.0], dtype=np.float32)
            self._corners = ctx.buffer(corners.tobytes())
            vx, rb = ctx.info["GL_MAX_VIEWPORT_DIMS"], ctx.info["GL_MAX_RENDERBUFFER_SIZE"]
        self.max_tile = int(min(vx[0], vx[1], rb, DEFAULT_MAX_TILE))
        if self._max_tile_arg is not None:
            self.max_tile = int(min(self.max_tile, self._max_tile_arg))

    def _framebuffer(self, width: int, height: int, slot: int = 0):
        """Slot ``slot``'s RGBA32F framebuffer of ``width × height`` (all slots are resized together)."""
        if self._target_size != (width, height):
            self._release(self._targets)
            self._targets, self._target_size = [], (width, height)
        while len(self._targets) <= slot:
            rb = self.ctx.renderbuffer((width, height), components=4, dtype="f4")
            self._targets.append((self.ctx.framebuffer(color_attachments=[rb]), rb))
        return self._targets[slot][0]

    def _upload(self, records: np.ndarray, slot: int = 0):
        """``records`` into slot ``slot``'s instance buffer (grown when too small); its vertex array."""
        data = memoryview(np.ascontiguousarray(records)).cast("B")
        while len(self._slots) <= slot:
            self._slots.append((None, None))
        buf, vao = self._slots[slot]
        if buf is None or buf.size < len(data):
            self._release([(vao, buf)])
            buf = self.ctx.buffer(reserve=max(len(data), 1 << 16))
            vao = self.ctx.vertex_array(
                self._prog,
                [
                    (self._corners, "2f", "in_corner"),
                    (buf, "4f 4f 4f/i", "in_mean_o_k", "in_conic_det", "in_color_r"),
                ],
            )
            self._slots[slot] = (buf, vao)
        buf.write(data)
        return vao

    @staticmethod
    def _release(pairs) -> None:
        for pair in pairs:
            for obj in pair:
                if obj is not None:
                    obj.release()

    # ------------------------------------------------------------------ rendering
    def render(self, scene, camera, background=(0.0, 0.0, 0.0)) -> np.ndarray:
        """(H, W, 3) float32 linear unclamped image of ``scene`` seen from ``camera``."""
        return self.draw(self.pack(scene, camera), background)

    def render_with_alpha(self, scene, camera, background=(0.0, 0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
        """``(image (H, W, 3), alpha (H, W))`` float32; alpha = 1 − T, the pixel's accumulated opacity
        (the transmittance T is the target's alpha channel; the image is ``C + T·background``)."""
        return self.draw(self.pack(scene, camera), background, with_alpha=True)

    def pack(self, scene, camera) -> PackedView:
        """Project, cull and depth-sort ``scene`` for ``camera`` once; :meth:`draw` it, or any
        ``.kept(mask)`` of it, as often as needed (a pruned set renders as its splats filtered from
        the full scene's view, bit for bit the render of the pruned scene)."""
        from renderers.projection import project_arrays, project_gaussians

        device = self.projection_device()
        if device is None:
            return pack_instances(project_arrays(scene, camera))
        import torch

        with torch.no_grad():
            return pack_instances(project_gaussians(scene, camera, device=device))

    def projection_device(self) -> str | None:
        """The torch device the splats are projected on, or None for numpy on the CPU: ``device``
        when given (``"cpu"`` means numpy); else CUDA when the machine has an NVIDIA GPU
        (``/dev/nvidiactl``; torch is imported only then, to ask whether it can use it)."""
        from harness.core.devices import default_device

        device = str(self.device) if self.device is not None else default_device()
        return None if device == "cpu" else device

    def render_projected(self, projected, background=(0.0, 0.0, 0.0), with_alpha: bool = False):
        """Composite already projected splats (a ``Projected`` of ``width × height``) into an image
        (and its alpha, ``with_alpha=True``)."""
        return self.draw(pack_instances(projected), background, with_alpha)

    def draw(self, view: PackedView, background=(0.0, 0.0, 0.0), with_alpha: bool = False):
        """Composite a packed view into an image (and its alpha, ``with_alpha=True``)."""
        self._ensure_context()
        bg = np.asarray(background, dtype=np.float32).reshape(3)
        with self.ctx:  # several renderers (contexts) may live in one process: make ours current
            image, alpha = self._draw(view.records, view.width, view.height, bg, with_alpha)
        return (image, alpha) if with_alpha else image

    def draw_many(self, views: list[PackedView], background=(0.0, 0.0, 0.0), with_alpha: bool = False) -> list:
        """:meth:`draw` of each view (bit for bit), every draw queued before the first read-back: the
        device is waited for once per batch, not once per image (each view has its own instance
        buffer and framebuffer, so no upload waits for an earlier draw). Views of different sizes, or
        larger than one tile, are drawn one by one."""
        self._ensure_context()
        if len(views) <= 1 or not self._stackable(views):
            return [self.draw(v, background, with_alpha) for v in views]
        (width, height), bg = (views[0].width, views[0].height), np.asarray(background, dtype=np.float32).reshape(3)
        out = []
        with self.ctx:
            self._queue(views)
            for i in range(len(views)):
                image, alpha = self._composed(self._targets[i][0], width, height, bg, with_alpha)
                out.append((image, alpha) if with_alpha else image)
        return out

    def draw_many_on(self, views: list[PackedView], device, background=(0.0, 0.0, 0.0), with_alpha: bool = False):
        """:meth:`draw_many` as ``(images (N, H, W, 3), alphas (N, H, W) or None)`` torch tensors on
        ``device``, each image bit for bit its :meth:`draw`: the batch's frames are read into one
        host buffer (pinned for CUDA) and copied to the device once (:mod:`renderers.readback`).
        Views must share one size; views larger than one tile are drawn one by one and stacked."""
        import torch

        from renderers import readback

        if len({(v.width, v.height) for v in views}) != 1:
            raise ValueError("draw_many_on needs packed views of one size")
        self._ensure_context()
        width, height = views[0].width, views[0].height
        if not self._stackable(views):
            outs = [self.draw(v, background, with_alpha=True) for v in views]
            images = torch.from_numpy(np.stack([o[0] for o in outs])).to(device)
            return images, torch.from_numpy(np.stack([o[1] for o in outs])).to(device) if with_alpha else None
        rgbt = readback.host_buffer(len(views), height, width, device)
        host, frame = rgbt.numpy(), width * height * 16
        with self.ctx:
            self._queue(views)
            for i in range(len(views)):
                self._targets[i][0].read_into(host, viewport=(0, 0, width, height), components=4, dtype="f4",
                                              write_offset=i * frame)
        return readback.to_device(rgbt, device, background, with_alpha)

    def _stackable(self, views: list[PackedView]) -> bool:
        """Whether ``views`` share one size that fits one framebuffer (drawn in one go each)."""
        sizes = {(v.width, v.height) for v in views}
        return len(sizes) == 1 and max(next(iter(sizes))) <= self.max_tile

    def _queue(self, views: list[PackedView]) -> None:
        """Draw each view into its own slot's framebuffer (context current, views :meth:`_stackable`)."""
        width, height = views[0].width, views[0].height
        self._begin(width, height, 0, 0, width, height)
        for i, v in enumerate(views):
            self._draw_tile(self._framebuffer(width, height, i), self._upload(v.records, i) if len(v.records)
                            else None, len(v.records), width, height)

    def _begin(self, width: int, height: int, x0: int, y0: int, w: int, h: int) -> None:
        """Blending (front to back: colour += T·cα, T ·= 1 − α) and the uniforms of an image's tile."""
        ctx, mgl, prog = self.ctx, self._moderngl, self._prog
        ctx.enable(mgl.BLEND)
        ctx.blend_func = mgl.DST_ALPHA, mgl.ONE, mgl.ZERO, mgl.ONE_MINUS_SRC_ALPHA
        ctx.blend_equation = mgl.FUNC_ADD
        prog["u_image"].value = (float(width), float(height))
        prog["u_tiles"].value = self.footprint == "tile"
        prog["u_origin"].value = (float(x0), float(y0))
        prog["u_size"].value = (float(w), float(h))

    def _draw_tile(self, fbo, vao, count: int, w: int, h: int) -> None:
        """Clear ``fbo`` to (0, 0, 0, T = 1) and draw ``count`` instances of ``vao`` into it."""
        fbo.use()
        fbo.viewport = (0, 0, w, h)
        fbo.clear(0.0, 0.0, 0.0, 1.0, viewport=(0, 0, w, h))
        if vao is not None:
            vao.render(self._moderngl.TRIANGLES, vertices=3, instances=count)

    @staticmethod
    def _composed(fbo, w: int, h: int, bg: np.ndarray, with_alpha: bool):
        """A tile's (Σ cᵢαᵢTᵢ, T) read back as ``C + T·bg`` (and 1 − T, or None)."""
        rgbt = np.frombuffer(fbo.read(viewport=(0, 0, w, h), components=4, dtype="f4"), dtype=np.float32)
        rgbt = rgbt.reshape(h, w, 4)
        return rgbt[..., :3] + rgbt[..., 3:4] * bg, (np.float32(1.0) - rgbt[..., 3]) if with_alpha else None

    def _draw(self, records: np.ndarray, width: int, height: int, bg: np.ndarray, with_alpha: bool = False):
        """Draw the records tile by tile; each tile's (Σ cᵢαᵢTᵢ, T) becomes ``C + T·bg`` (and 1 − T)."""
        tile = min(self.max_tile, max(width, height))
        fbo = self._framebuffer(min(tile, width), min(tile, height))
        vao = self._upload(records) if len(records) else None
        image = np.empty((height, width, 3), dtype=np.float32)
        alpha = np.empty((height, width), dtype=np.float32) if with_alpha else None
        for x0, y0, w, h in tiles(width, height, tile):
            self._begin(width, height, x0, y0, w, h)
            self._draw_tile(fbo, vao, len(records), w, h)
            wait_without_gil()
            img, a = self._composed(fbo, w, h, bg, with_alpha)
            image[y0 : y0 + h, x0 : x0 + w] = img
            if with_alpha:
                alpha[y0 : y0 + h, x0 : x0 + w] = a
        return image, alpha

    def close(self) -> None:
        """Release every GL object and the context (a later render creates a new one)."""
        if self.ctx is None:
            return
        with self.ctx:
            self._release([*self._slots, *self._targets, (self._corners, self._prog)])
        self.ctx.release()
        self.ctx, self._targets, self._target_size, self._slots = None, [], None, []

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
