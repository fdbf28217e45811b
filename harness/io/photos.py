"""A capture's photos: found by camera name, checked against their cameras, read at a render size.

* **Matching**: a camera named ``DSCF5565`` (or ``DSCF5565.JPG``) is matched to the image in the
  photo folder — or one level of sub-folders (``images/test/``) — whose stem is the camera name's
  stem, case kept; ``.png``, ``.jpg`` and ``.jpeg`` are read. Two images with one stem are ambiguous.
* **Size**: a photo is its camera's image scaled by one factor: with ``k`` = photo long side /
  camera long side, the short side must be within one pixel of ``k ×`` the camera's short side
  (rounding), else it is another aspect. Every photo of a capture has the same ``k`` (Mip-NeRF 360's
  ``images_4`` are a quarter of the camera size): a photo at another scale is refused too.
* **Reading at a render size**: 8-bit values / 255 as float32, then each channel area-averaged
  (PIL ``BOX`` on the float channel, so no 8-bit rounding) to the render's width × height: each render
  pixel gets the mean of the photo pixels it covers. A render larger than the photo is never asked
  for: the ``real`` protocol caps its size at the photos' (:mod:`harness.io.capture`).

Files are read through :mod:`harness.io.safe` (regular files, size-capped); sizes come from the
image header, pixels are decoded only when a photo is read.
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from harness.core.cameras import MAX_PIXELS, MAX_SIDE, Camera
from harness.core.errors import InputError

EXTENSIONS = (".png", ".jpg", ".jpeg")


def photo_index(folder: Path) -> dict[str, Path]:
    """Stem -> image file of ``folder`` and its direct sub-folders (ambiguous stems refused)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(folder, "photo folder not found (or not a folder)")
    found: dict[str, Path] = {}
    for p in sorted([*folder.iterdir(), *(q for d in sorted(folder.iterdir()) if d.is_dir() for q in d.iterdir())]):
        if p.suffix.lower() in EXTENSIONS and p.is_file():
            if p.stem in found:
                raise InputError(folder, f"two photos named {p.stem!r}: {found[p.stem]} and {p}")
            found[p.stem] = p
    return found


def photo_stem(name: str) -> str:
    return Path(name).stem if Path(name).suffix.lower() in (*EXTENSIONS, ".tif", ".tiff") else name


def match_photos(cameras: list[Camera], folder: Path, source) -> dict[str, Path]:
    """Camera name -> its photo, for every camera; a missing photo is one line naming it."""
    index = photo_index(folder)
    out, missing = {}, []
    for cam in cameras:
        p = index.get(photo_stem(cam.name))
        if p is None:
            missing.append(cam.name)
        else:
            out[cam.name] = p
    if missing and not out:
        have = ", ".join(sorted(index)[:4]) or "none"
        raise InputError(source, f"the camera names ({', '.join(c.name for c in cameras[:3])}, ...) match no photo in "
                                 f"{folder} (its photos: {have}{', ...' if len(index) > 4 else ''})")
    if missing:
        raise InputError(folder, f"no photo for {len(missing)} held-out camera(s) of {source}: "
                                 f"{', '.join(missing[:5])}{', ...' if len(missing) > 5 else ''}")
    return out


def photo_size(path: Path) -> tuple[int, int]:
    """(width, height) from the image header."""
    from PIL import Image, UnidentifiedImageError

    from harness.io.safe import open_regular, pillow_problem

    with open_regular(path, "image", "photo") as f:
        try:
            with Image.open(f) as im:
                if im.format not in ("PNG", "JPEG"):
                    raise InputError(path, f"is a {im.format} image; photos are PNG or JPEG")
                w, h = im.size
        except (UnidentifiedImageError, OSError, SyntaxError, ValueError, Image.DecompressionBombError) as err:
            f.seek(0)
            raise InputError(path, f"not a readable photo: {pillow_problem(err, f.read(24))}") from None
    if w > MAX_SIDE or h > MAX_SIDE or w * h > MAX_PIXELS:
        raise InputError(path, f"photo is {w}x{h} pixels, larger than the maximum ({MAX_SIDE} per side)")
    return w, h


def scale_of(photo: tuple[int, int], cam: Camera) -> float | None:
    """The factor taking the camera's image to the photo, or None when the aspect differs."""
    pw, ph = photo
    if cam.width >= cam.height:  # the long side sets the scale, the short side must follow it
        k, short_c, short_p = pw / cam.width, cam.height, ph
    else:
        k, short_c, short_p = ph / cam.height, cam.width, pw
    return k if abs(short_c * k - short_p) <= 1.0 else None


def check_photos(photos: dict[str, Path], cameras: dict[str, Camera], decode: bool = True) -> tuple[int, int]:
    """Every photo is its camera's image at one common scale (module docstring) and, with ``decode``,
    decodes (a truncated photo fails here, at load, not when its view is rendered); returns the
    (width, height) of the first photo."""
    first = None
    for name, path in photos.items():
        size, cam = photo_size(path), cameras[name]
        if decode:
            read_photo(path, *size)
        k = scale_of(size, cam)
        if k is None:
            raise InputError(path, f"photo is {size[0]}x{size[1]} (aspect {size[0] / size[1]:.3f}) but its camera "
                                   f"{name!r} is {cam.width}x{cam.height} (aspect {cam.width / cam.height:.3f}): "
                                   "not that camera's image")
        if first is None:
            first = (size, k, name)
        elif abs(k - first[1]) * max(cam.width, cam.height) > 1.0:
            raise InputError(path, f"photo is {size[0]}x{size[1]}, {k:.4g} x its camera, but {first[2]!r} is "
                                   f"{first[0][0]}x{first[0][1]}, {first[1]:.4g} x its camera: a capture's photos "
                                   "share one scale")
    return first[0] if first else (0, 0)


def read_photo(path: Path, width: int, height: int) -> np.ndarray:
    """The photo as float32 (height, width, 3) in [0, 1], area-averaged to that size."""
    from PIL import Image, UnidentifiedImageError

    from harness.io.safe import pillow_problem, read_bytes

    photo_size(path)  # header checks before decoding
    data = read_bytes(path, "image", "photo")
    try:
        with Image.open(io.BytesIO(data)) as im:
            im.load()
            if im.mode not in ("RGB", "L", "RGBA", "LA", "P"):
                raise InputError(path, f"photo mode {im.mode} is not 8-bit colour or grey")
            rgb = np.asarray(im.convert("RGB"), np.float32) / np.float32(255.0)
    except (UnidentifiedImageError, OSError, SyntaxError, ValueError, Image.DecompressionBombError) as err:
        raise InputError(path, f"not a readable photo: {pillow_problem(err, data[:24])}") from None
    if rgb.shape[:2] == (height, width):
        return rgb
    if width > rgb.shape[1] or height > rgb.shape[0]:
        raise InputError(path, f"photo is {rgb.shape[1]}x{rgb.shape[0]}, smaller than the render "
                               f"{width}x{height}: it would be upsampled")
    return np.stack([np.asarray(Image.fromarray(np.ascontiguousarray(rgb[:, :, c]), "F")
                                .resize((width, height), Image.Resampling.BOX), np.float32)
                     for c in range(3)], axis=2)
