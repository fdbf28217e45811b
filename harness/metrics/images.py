"""Reading and validating the images that metrics compare.

An *image* here is a float32 array ``(H, W, 3)`` of linear colour nominally in [0, 1]; metrics clamp
to [0, 1] themselves, so readers do not. Bad images raise :class:`~harness.core.errors.InputError`.

File readings (the decisions):
* PNG (8-bit grey, grey+alpha, RGB, RGBA, palette; 16-bit grey): integer values divided by 255 or
  65535. 16-bit *colour* and 16-bit *grey+alpha* PNGs are refused (Pillow would silently reduce
  them to 8 bits).
* Size: files are read through :mod:`harness.io.safe` (regular files only, size-capped), and an
  image larger than the maximum render size (:data:`harness.core.cameras.MAX_SIDE` per side) is
  refused from its header (PNG IHDR, ``.npy`` shape) before any pixel is decoded. Grey is
  replicated to three channels; **alpha is dropped** (colour compared as stored, not
  composited) because the renderers write opaque RGB over a known background.
* ``.npy`` (loaded without pickle): float arrays kept as they are (cast to float32), ``uint8`` /
  ``uint16`` scaled like PNG, shapes ``(H, W)``, ``(H, W, 1)``, ``(H, W, 3)`` or ``(H, W, 4)`` handled
  as for PNG. NaN or infinite pixels are an error (a metric of them would be meaningless).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from harness.core.errors import InputError

_INT_SCALE = {np.dtype(np.uint8): 255.0, np.dtype(np.uint16): 65535.0}


def as_image(array, source: str | Path = "image") -> np.ndarray:
    """Validate and normalise ``array`` to float32 ``(H, W, 3)`` (see module docstring)."""
    a = np.asarray(array)
    if a.dtype in _INT_SCALE:
        a = a.astype(np.float32) / np.float32(_INT_SCALE[a.dtype])
    elif a.dtype.kind == "f":
        a = a.astype(np.float32, copy=False)
    else:
        raise InputError(source, f"pixel type {a.dtype} is not supported (use float, uint8 or uint16)")
    if a.ndim == 2:
        a = a[:, :, None]
    if a.ndim != 3 or a.shape[2] not in (1, 2, 3, 4):
        raise InputError(source, f"shape {a.shape} is not an image (H, W), (H, W, 1|3|4)")
    if a.shape[0] == 0 or a.shape[1] == 0:
        raise InputError(source, f"image is empty ({a.shape[0]}x{a.shape[1]})")
    if a.shape[2] in (1, 2):
        a = np.repeat(a[:, :, :1], 3, axis=2)
    a = np.ascontiguousarray(a[:, :, :3])
    bad = ~np.isfinite(a)
    if bad.any():
        y, x, _ = np.argwhere(bad)[0]
        raise InputError(source, f"{int(bad.sum())} NaN or infinite pixel values (first at row {y}, column {x})")
    return a


def _check_dims(path, w: int, h: int) -> None:
    from harness.core.cameras import MAX_PIXELS, MAX_SIDE

    if w > MAX_SIDE or h > MAX_SIDE or w * h > MAX_PIXELS:
        raise InputError(path, f"image is {w}x{h} pixels, larger than the maximum ({MAX_SIDE} per side)")


def header_size(path: str | Path) -> tuple[int, int] | None:
    """(width, height) from a PNG's IHDR or a ``.npy`` header, nothing decoded; None when the
    header says nothing readable (:func:`read_image` then says what is wrong)."""
    from harness.io.safe import npy_header, open_regular

    path = Path(path)
    with open_regular(path, "image", "image file") as f:
        if path.suffix.lower() == ".npy":
            try:
                shape = npy_header(f, path)[0]
            except InputError:
                return None
            return (shape[1], shape[0]) if len(shape) >= 2 else None
        head = f.read(24)
    if head[:8] == b"\x89PNG\r\n\x1a\n" and head[12:16] == b"IHDR":
        return int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")
    return None


def read_image(path: str | Path) -> np.ndarray:
    """Read a PNG or ``.npy`` image file as float32 ``(H, W, 3)``."""
    from harness.io.safe import check_regular, load_npy

    path = Path(path)
    check_regular(path, "image", "image file")
    if path.suffix.lower() == ".npy":
        from harness.core.cameras import MAX_PIXELS

        array = load_npy(path, "image", max_elements=4 * MAX_PIXELS)
        if array.ndim >= 2:
            _check_dims(path, array.shape[1], array.shape[0])
        return as_image(array, path)
    return as_image(_read_png(path), path)


def _read_png(path: Path) -> np.ndarray:
    import io

    from PIL import Image, UnidentifiedImageError

    from harness.io.safe import pillow_problem, read_bytes

    data = read_bytes(path, "image", "image file")
    head = data[:26]
    # IHDR: signature (8) + length (4) + "IHDR" (4) + width, height (8) + bit depth + colour type
    if len(head) == 26 and head[12:16] == b"IHDR":
        w, h = int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")
        if w == 0 or h == 0:
            raise InputError(path, f"image is empty: its PNG header says {w}x{h} pixels")
        _check_dims(path, w, h)
        if head[24] == 16 and head[25] in (2, 6):
            raise InputError(path, "16-bit colour PNG is not supported (Pillow reads it as 8-bit); save it as .npy")
        if head[24] == 16 and head[25] == 4:
            raise InputError(path, "16-bit grey+alpha PNG is not supported (Pillow reads it as 8-bit); "
                                   "save it as .npy or as 16-bit grey")
    try:
        with Image.open(io.BytesIO(data)) as im:
            if im.format != "PNG":
                raise InputError(path, f"is a {im.format} image; only PNG and .npy are read")
            _check_dims(path, *im.size)
            im.load()
            if im.mode == "P":
                im = im.convert("RGBA")
            if im.mode in ("I;16", "I;16B", "I;16L", "I"):
                return np.asarray(im, dtype=np.int64).clip(0, 65535).astype(np.uint16)
            if im.mode not in ("L", "LA", "RGB", "RGBA"):
                im = im.convert("RGB")
            return np.asarray(im, dtype=np.uint8)
    except (UnidentifiedImageError, OSError, SyntaxError, ValueError, Image.DecompressionBombError) as err:
        raise InputError(path, f"not a readable PNG image: {pillow_problem(err, head)}") from None


def check_same_size(a: np.ndarray, b: np.ndarray, source_a="first image", source_b="second image") -> None:
    """Raise :class:`InputError` unless the two images have the same height and width."""
    if a.shape[:2] != b.shape[:2]:
        raise InputError(
            f"{source_a} vs {source_b}",
            f"image sizes differ: {a.shape[1]}x{a.shape[0]} vs {b.shape[1]}x{b.shape[0]} (width x height)",
        )
