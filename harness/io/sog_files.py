"""The files of a PlayCanvas SOG set, read safely: from its folder or from a ``.sog`` zip bundle.

Every file is read through :mod:`harness.io.safe` (regular files only, size-capped) and must lie
inside the scene's folder (the folder of the ``meta.json`` or ``lod-meta.json`` given): absolute
names, ``..`` climbing out and symlinks leading out are refused. Sizes are bounded before anything
is inflated or decoded: a JSON file (a bundle member too) at most the JSON cap; a texture of ``P``
allowed pixels at most :func:`image_bytes` ``(P)`` bytes — checked on the size on disk or in the
zip directory, and again while inflating a member (read up to the cap and no further), so a small
``.sog`` claiming or inflating to hundreds of MiB is refused after at most the cap; its header's
pixel count is checked against ``P`` before decoding (``P``: :data:`MAX_PIXELS`, at most
``2·count + 65536`` when the splat count is known, exactly the palette's size for SH centroids).
Lossy WebP is refused: the codes must be exact.
"""

from __future__ import annotations

import io
import zipfile
from pathlib import Path
from typing import Self

import numpy as np

from harness.core.errors import InputError

#: most splats one SOG file may declare, and most pixels one texture may decode to (64 Mi: a
#: 8192x8192 texture, ~20x the largest published scenes; WebP itself stops at 16383x16383)
MAX_PIXELS = 1 << 26


class SogFiles:
    """Reads sibling files of a SOG set from a folder or a ``.sog`` zip."""

    def __init__(self, root: Path, zip_path: Path | None = None, top: str | None = None):
        from harness.io.safe import open_regular

        self.root, self.zip_path = root, zip_path
        self.top = top  # the metadata file the user named: read as given (the folder is its own)
        self._handle = open_regular(zip_path, "scene", ".sog bundle") if zip_path else None
        try:
            self._zip = zipfile.ZipFile(self._handle) if zip_path else None
        except BaseException:
            self._handle.close()
            raise

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc) -> None:
        if self._zip:
            self._zip.close()
        if self._handle:
            self._handle.close()

    def label(self, name: str) -> str:
        return f"{self.zip_path}:{name}" if self._zip else str(self.root / name)

    def read(self, name: str, cap: int | None = None) -> bytes:
        """The bytes of ``name``: at most the JSON or image limit, and at most ``cap`` (refused beyond,
        from the size on disk or in the zip directory, and again while inflating)."""
        from harness.io.safe import confined, read_bytes

        if not isinstance(name, str) or not name:
            raise InputError(self.label(str(name)), "bad file name in the SOG metadata")
        kind = "json" if name.endswith(".json") else "image"
        cap = _limit(kind) if cap is None else min(cap, _limit(kind))
        try:
            if self._zip:
                info = self._zip.getinfo(name)
                _check_size(self.label(name), info.file_size, cap, kind)
                with self._zip.open(info) as member:  # inflated up to the cap, never further
                    data = member.read(cap + 1)
                _check_size(self.label(name), len(data), cap, kind, inflated=True)
                return data
            path = self.root / name if name == self.top else confined(self.root, name, self.label(name))
            if not path.exists():
                raise InputError(self.label(name), "missing (referenced by the SOG metadata)")
            if path.is_file():
                _check_size(self.label(name), path.stat().st_size, cap, kind)
            return read_bytes(path, kind, "SOG file")
        except KeyError:
            raise InputError(self.label(name), "missing from the .sog bundle") from None
        except (zipfile.BadZipFile, OSError, RuntimeError, EOFError) as err:
            raise InputError(self.label(name), f"cannot read: {getattr(err, 'strerror', None) or err}") from None

    def json(self, name: str) -> dict:
        from harness.io.safe import parse_json

        meta = parse_json(self.read(name), self.label(name))
        if not isinstance(meta, dict):
            raise InputError(self.label(name), "expected a JSON object")
        return meta

    def image(self, name: str, count: int | None, pixels: int | None = None) -> np.ndarray:
        """(H, W, 4) uint8 pixels; checks there are at least ``count`` of them and at most ``pixels``
        (default: the bound of ``count`` splats), before inflating and before decoding."""
        from PIL import Image, UnidentifiedImageError

        from harness.io.safe import pillow_problem

        if pixels is None:
            pixels = MAX_PIXELS if count is None else min(MAX_PIXELS, 2 * count + 65536)
        data = self.read(name, image_bytes(pixels))
        if _is_lossy_webp(data):
            raise InputError(self.label(name), "lossy WebP image; SOG codes need lossless images")
        try:
            with Image.open(io.BytesIO(data)) as img:
                w, h = img.size
                if w * h > pixels:  # checked on the header, before decoding
                    raise InputError(self.label(name), f"image is {w}x{h} pixels, more than the {pixels:,} "
                                                       f"allowed{'' if count is None else f' for {count} splats'}")
                decoded = np.asarray(img.convert("RGBA"))
        except (UnidentifiedImageError, OSError, ValueError, Image.DecompressionBombError) as err:
            raise InputError(self.label(name), f"cannot decode image ({pillow_problem(err)})") from None
        if count is not None and decoded.shape[0] * decoded.shape[1] < count:
            raise InputError(self.label(name), f"image has {decoded.shape[1]}x{decoded.shape[0]} pixels, "
                                               f"fewer than the {count} splats declared")
        return decoded


def image_bytes(pixels: int) -> int:
    """Most bytes a texture of ``pixels`` pixels may take: 8 per pixel (lossless WebP of noise takes
    about 4) plus 1 MiB for headers and metadata chunks."""
    return 8 * pixels + (1 << 20)


def _check_size(label: str, size: int, cap: int, kind: str, inflated: bool = False) -> None:
    """Refuse ``size`` bytes over ``cap`` (``inflated``: the member was read up to ``cap + 1``)."""
    if size > cap:
        allowed = "for a JSON file (HARNESS_MAX_JSON_BYTES raises it)" if kind == "json" else \
            "for a texture of the splats declared"
        amount = f"inflates to more than {cap:,} bytes" if inflated else f"is {size:,} bytes"
        raise InputError(label, f"{amount}, over the {cap:,} allowed {allowed}")


def _limit(kind: str) -> int:
    from harness.io.safe import limit

    return limit(kind)


def _is_lossy_webp(data: bytes) -> bool:
    """True for a RIFF/WEBP whose image chunk is ``VP8 `` (lossy) rather than ``VP8L``."""
    if data[:4] != b"RIFF" or data[8:12] != b"WEBP":
        return False
    pos = 12
    while pos + 8 <= len(data):
        fourcc, size = data[pos:pos + 4], int.from_bytes(data[pos + 4:pos + 8], "little")
        if fourcc in (b"VP8 ", b"VP8L"):
            return fourcc == b"VP8 "
        pos += 8 + size + (size & 1)
    return False


def named_files(meta_path: str | Path) -> list[Path]:
    """The files a ``meta.json`` names (each property's ``files``), beside it; [] when it cannot be
    read as SOG metadata (the reader says why when the scene is read)."""
    from harness.io.safe import read_json

    meta_path = Path(meta_path)
    try:
        meta = read_json(meta_path, record=False)
    except InputError:
        return []
    names = []
    for key in ("means", "scales", "quats", "sh0", "shN"):
        entry = meta.get(key) if isinstance(meta, dict) else None
        files = entry.get("files") if isinstance(entry, dict) else None
        names += [f for f in files if isinstance(f, str) and f] if isinstance(files, list) else []
    return [meta_path.parent / name for name in names]
