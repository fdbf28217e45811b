"""PlayCanvas SOG writer: ``meta.json`` + lossless WebP textures in a folder, or the same files in
one ``.sog`` zip, as PlayCanvas splat-transform writes them (``src/lib/writers/write-sog.ts``,
``zip-file-system.ts``, v3.2.0, read and restated; layout and decoding in :mod:`harness.io.sog`).

Per splat, in Morton order of the positions (:func:`harness.io.compressed_ply.morton_order`; the
file's rows are reordered), texel ``i`` of every per-splat texture (``W = 4·ceil(√N / 4)`` wide,
``H = 4·ceil(N / W / 4)`` high, row-major, unused texels zero):

* means: ``v = sign(x)·ln(1 + |x|)`` per axis; ``mins``/``maxs`` are ``v`` of the scene's bounding
  box; ``q = round(65535·(v − min)/(max − min))`` (0 when ``max = min``), low byte in
  ``means_l``, high byte in ``means_u``, alpha 255.
* quats: normalised, negated so the largest |component| ``m`` of (w, x, y, z) is positive (the
  first of equal ones); the other three, in order, times √2, as ``round(255·(v/2 + ½))``;
  alpha ``252 + m``.
* scales: the three log-scales coded by one 256-entry codebook (:func:`codebook_1d`), alpha 255.
* sh0: the three ``f_dc`` coded by another; alpha ``round(255·sigmoid(opacity))``.
* shN (SH degree ≥ 1): the ``3·K`` coefficients of each splat are clustered into a palette of
  ``min(64, 2^floor(log2(N/1024)))·1024`` entries, ``N`` up to 1024 splats (:func:`kmeans_palette`,
  10 Lloyd iterations as splat-transform's default; entries no splat uses are dropped, and
  ``shN.count`` is the number kept); every palette value is coded by a third codebook;
  ``shN_labels`` holds the entry (R low byte, G high byte), ``shN_centroids`` entry ``p`` at row
  ``p // 64``, columns ``(p % 64)·K + k`` (RGB: the colour channels of coefficient ``k``).

Where splat-transform truncates a scaled value to its byte (means, quaternions, alpha) this writer
rounds: the same decoding, half the error. Textures are lossless WebP from Pillow's libwebp
(``lossless``, ``exact``: RGB under alpha 0 kept, so an invisible splat keeps its colour codes).
``meta.json`` is compact JSON (``version`` 2, ``asset.generator``, ``count``, per property its
``files`` and codebook or range, ``shN.count``/``bands``). The bundle is a zip of the textures then
``meta.json``, stored (WebP is compressed already), every member dated 1980-01-01: the same scene
gives the same bytes. The folder form writes the textures beside the named ``meta.json``; the old
``meta.json`` is removed first and the new one written last, so the folder never holds a
``meta.json`` whose textures are of another scene. Lossy: extra properties and header comments are
not stored; bounds in ``tests/test_sog_write.py``.
"""

from __future__ import annotations

import io
import json
import math
import os
from pathlib import Path

import numpy as np

from harness.core.errors import InputError
from harness.core.scene import GaussianScene, normalized_quats, sigmoid
from harness.io.codebook import codebook_1d, kmeans_palette

ITERATIONS = 10
SEED = 0
MAX_SIDE = 16383  # WebP's largest width or height
TEXTURES = ("means_l.webp", "means_u.webp", "quats.webp", "scales.webp", "sh0.webp",
            "shN_centroids.webp", "shN_labels.webp")
_DATE = (1980, 1, 1, 0, 0, 0)


def texture_size(n: int, source="scene") -> tuple[int, int]:
    """(width, height) of the per-splat textures of ``n`` splats."""
    if n <= 0:
        raise InputError(source, "a SOG scene cannot hold 0 splats (its textures would have no pixels)")
    width = 4 * math.ceil(math.sqrt(n) / 4)
    height = 4 * math.ceil(n / width / 4)
    if max(width, height) > MAX_SIDE:
        raise InputError(source, f"{n:,} splats need {width}x{height} textures, beyond WebP's {MAX_SIDE} per side")
    return width, height


def palette_size(n: int) -> int:
    """Entries of the SH palette of ``n`` splats: ``min(64, 2^floor(log2(n/1024)))·1024``, and one per
    splat up to 1024 splats (where that formula would give fewer entries than splats)."""
    return n if n <= 1024 else int(min(64.0, 2.0 ** math.floor(math.log2(n / 1024))) * 1024)


def log_means(means: np.ndarray) -> np.ndarray:
    """``sign(x)·ln(1 + |x|)`` in float64."""
    m = np.asarray(means, np.float64)
    return np.sign(m) * np.log1p(np.abs(m))


def encode_means(means: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(16-bit codes (N, 3), mins (3,), maxs (3,)) of the log-transformed positions."""
    v = log_means(means)
    lo, hi = v.min(0), v.max(0)
    span = hi - lo
    q = np.where(span > 0, np.rint(65535.0 * (v - lo) / np.where(span > 0, span, 1.0)), 0.0)
    return np.clip(q, 0, 65535).astype(np.uint16), lo, hi


def position_error(means: np.ndarray) -> np.ndarray:
    """How far each splat's decoded centre lies from ``means`` (max over axes), as the reader decodes."""
    from harness.io.sog import decode_means

    q, lo, hi = encode_means(means)
    return np.abs(decode_means(q, lo, hi).astype(np.float32) - np.asarray(means, np.float64)).max(1, initial=0.0)


def encode_quats(quats: np.ndarray) -> np.ndarray:
    """(N, 4) uint8 smallest-three codes of (w, x, y, z) quaternions (module docstring)."""
    q = normalized_quats(np.asarray(quats, np.float64))
    n = len(q)
    largest = np.abs(q).argmax(1)
    q = q * (np.where(q[np.arange(n), largest] < 0, -1.0, 1.0) * math.sqrt(2.0))[:, None]
    slots = np.array([[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]])[largest]
    others = np.clip(np.rint(255.0 * (q[np.arange(n)[:, None], slots] * 0.5 + 0.5)), 0, 255)
    return np.concatenate([others, (252 + largest)[:, None]], 1).astype(np.uint8)


def _rgba(rgb: np.ndarray, alpha) -> np.ndarray:
    out = np.empty((len(rgb), 4), np.uint8)
    out[:, :3] = rgb
    out[:, 3] = alpha
    return out


def _sh_rest(scene: GaussianScene, source) -> tuple[dict, np.ndarray, np.ndarray]:
    """(meta ``shN``, centroid texture (rows, 64·K, 4), labels (N, 4)) of the SH beyond degree 0."""
    n, k = scene.sh_rest.shape[:2]
    entries = palette_size(n)
    centroids, labels = kmeans_palette(scene.sh_rest.reshape(n, 3 * k), entries, ITERATIONS, SEED)
    book, codes = codebook_1d(centroids, source)
    rows = -(-len(centroids) // 64)
    cent = np.zeros((rows * 64, k, 4), np.uint8)
    cent[: len(centroids), :, :3] = codes.reshape(-1, k, 3)
    cent[: len(centroids), :, 3] = 255
    lab = _rgba(np.stack([labels & 0xFF, labels >> 8, np.zeros_like(labels)], 1), 255)
    meta = {"count": len(centroids), "bands": scene.sh_degree, "codebook": book.tolist(),
            "files": ["shN_centroids.webp", "shN_labels.webp"]}
    return meta, cent.reshape(rows, 64 * k, 4), lab


def webp(pixels: np.ndarray) -> bytes:
    """Lossless WebP of an (H, W, 4) uint8 image, every RGBA value kept (``exact``)."""
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(pixels), "RGBA").save(buf, "WEBP", lossless=True, exact=True, quality=70,
                                                               method=4)
    return buf.getvalue()


def _generator() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return f"betadesc-harness v{version('betadesc-harness')}"
    except PackageNotFoundError:
        return "betadesc-harness"


def encode_sog(scene: GaussianScene, source="scene") -> tuple[dict[str, bytes], np.ndarray]:
    """({file name: bytes}, row order) of ``scene`` as SOG: textures first, ``meta.json`` last; file row
    ``j`` is scene row ``order[j]``."""
    from harness.io.compressed_ply import morton_order

    n = len(scene)
    width, height = texture_size(n, source)
    order = morton_order(scene.means)
    s = scene.subset(order)

    def texture(rows: np.ndarray) -> bytes:
        full = np.zeros((width * height, 4), np.uint8)
        full[:n] = rows
        return webp(full.reshape(height, width, 4))

    q, mins, maxs = encode_means(s.means)
    scale_book, scale_codes = codebook_1d(s.scales_log, source)
    dc_book, dc_codes = codebook_1d(s.sh_dc, source)
    alpha = np.clip(np.rint(255.0 * sigmoid(s.opacity_logit.astype(np.float64))), 0, 255)
    files = {"means_l.webp": texture(_rgba(q & 0xFF, 255)), "means_u.webp": texture(_rgba(q >> 8, 255)),
             "quats.webp": texture(encode_quats(s.quats)), "scales.webp": texture(_rgba(scale_codes, 255)),
             "sh0.webp": texture(_rgba(dc_codes, alpha))}
    meta = {"version": 2, "asset": {"generator": _generator()}, "count": n,
            "means": {"mins": mins.tolist(), "maxs": maxs.tolist(), "files": ["means_l.webp", "means_u.webp"]},
            "scales": {"codebook": scale_book.tolist(), "files": ["scales.webp"]},
            "quats": {"files": ["quats.webp"]},
            "sh0": {"codebook": dc_book.tolist(), "files": ["sh0.webp"]}}
    if scene.sh_degree:
        meta["shN"], centroids, labels = _sh_rest(s, source)
        files["shN_centroids.webp"] = webp(centroids)
        files["shN_labels.webp"] = texture(labels)
    files["meta.json"] = json.dumps(meta, separators=(",", ":"), allow_nan=False).encode("utf-8")
    return files, order


def bundle(files: dict[str, bytes]) -> bytes:
    """The ``.sog`` zip of ``files`` (in order, stored, fixed dates)."""
    import zipfile

    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_STORED) as z:
        for name, data in files.items():
            info = zipfile.ZipInfo(name, date_time=_DATE)
            info.create_system, info.external_attr = 3, 0o644 << 16
            z.writestr(info, data)
    return buf.getvalue()


def output_files(path) -> list[Path]:
    """Every file writing ``path`` may replace: the bundle itself, or ``meta.json`` and its textures."""
    path = Path(path)
    if path.name.lower().endswith(".sog"):
        return [path]
    return [path.parent / name for name in TEXTURES] + [path]


def write_sog(scene: GaussianScene, path) -> np.ndarray:
    """Write ``scene`` as a ``.sog`` bundle or a ``meta.json`` folder set (module docstring), each file
    atomically; returns the row order."""
    from harness.io.files import atomic_write_bytes

    path = Path(path)
    files, order = encode_sog(scene, path)
    if path.name.lower().endswith(".sog"):
        atomic_write_bytes(path, bundle(files))
        return order
    _write_folder(path, files)
    return order


def _write_folder(path: Path, files: dict[str, bytes]) -> None:
    """Textures beside ``path`` (all checked, then each written atomically), then ``path`` itself."""
    from harness.io.files import atomic_write_bytes, refuse_inputs

    folder = path.parent
    textures = {folder / name: data for name, data in files.items() if name != "meta.json"}
    refuse_inputs(path, *textures)  # before anything is replaced
    try:
        os.unlink(path)
    except FileNotFoundError:
        pass
    except OSError as err:
        raise InputError(path, f"cannot replace: {err.strerror or err}") from None
    for target, data in textures.items():
        atomic_write_bytes(target, data)
    atomic_write_bytes(path, files["meta.json"])
