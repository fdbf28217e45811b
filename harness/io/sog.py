"""PlayCanvas SOG v2 reader (``meta.json`` + lossless WebP textures), single files or LOD sets.

Decoding follows PlayCanvas splat-transform's SOG v2 reader/writer (read from their sources);
texture pixel ``i`` (row-major) holds splat ``i``:

* means: ``q = means_l + 256·means_u`` per RGB channel (16 bit);
  ``v = min + (max − min)·q/65535`` (``max − min`` taken as 1 when zero) and the writer's
  ``v = sign(x)·ln(1 + |x|)`` is inverted: ``x = sign(v)·(e^|v| − 1)``.
* quats (smallest three): alpha ``252 + m`` names the largest component ``m`` of (w, x, y, z);
  RGB hold the other three in order as ``byte/255·2 − 1``, scaled by √2 (so divide by √2); the
  largest is ``sqrt(max(0, 1 − Σ others²))``, positive. An alpha outside 252..255 decodes to the
  identity, as the reference reader does.
* scales: each RGB byte indexes the 256-entry ``scales.codebook`` of log-scales.
* sh0: RGB bytes index ``sh0.codebook`` (f_dc); alpha is sigmoid(opacity)·255, decoded as
  ``logit(clip(a/255, 1e-6, 1 − 1e-6))`` (the reference reader's clamp).
* shN: ``label = R + 256·G`` of ``shN_labels``; the centroid texture is ``64·K`` pixels wide with
  palette entry ``p`` at row ``p // 64``, columns ``(p % 64)·K + k`` for coefficient k, RGB = the
  three colour channels, each byte indexing ``shN.codebook``; K = 3, 8, 15 for ``bands`` 1..3.
  Labels ≥ ``shN.count`` give zero coefficients (reference behaviour).

``lod-meta.json`` (streamed LOD): level L is the union over the ``tree`` of ``lods[L]`` references
``{file, offset, count}``: rows ``offset .. offset+count`` of the SOG file ``filenames[file]``,
taken in file order then offset order. ``lod=None`` means level 0 (the full-detail scene);
``lod="all"`` concatenates every level 0..L−1, as splat-transform does without a LOD selection.
The optional ``environment`` SOG is not read.

Inputs accepted: a folder holding ``lod-meta.json`` or ``meta.json``, either JSON file, or a
``.sog`` zip bundle. Its files are read by :mod:`harness.io.sog_files`: confined to the scene's
folder, regular, and bounded before anything is inflated or decoded (lossy WebP refused: the codes
must be exact). LOD references must be integers (``offset ≥ 0``, ``count ≥ 0``), name a listed
file, and the ranges of one level may not overlap, so a level holds each stored splat at most once
(no expansion beyond the referenced data). The writer is :mod:`harness.io.sog_write`.
"""

from __future__ import annotations

import posixpath
import zipfile
from pathlib import Path

import numpy as np

from harness.core.errors import InputError
from harness.core.scene import SH_REST_COUNT, GaussianScene
from harness.io.sog_files import MAX_PIXELS, SogFiles

_SQRT2 = np.sqrt(2.0)
_OPACITY_EPS = 1e-6
_MAX_COUNT = MAX_PIXELS
_MAX_LOD_LEVELS = 64
_MAX_TREE_NODES = 10_000_000
_MAX_META_VALUE = 1e30  # codebooks / ranges beyond this overflow float32 maths downstream


def _get(meta: dict, files: SogFiles, name: str, *keys):
    """``meta[k0][k1]...``; string keys index objects, integer keys index lists."""
    node = meta
    for key in keys:
        present = (isinstance(node, dict) and key in node) if isinstance(key, str) \
            else (isinstance(node, list) and 0 <= key < len(node))
        if not present:
            raise InputError(files.label(name), f"SOG metadata lacks '{'.'.join(map(str, keys))}'")
        node = node[key]
    return node


def _numbers(meta, files, name, *keys, length: int) -> np.ndarray:
    """A list of ``length`` finite numbers at ``meta[keys]`` as float64 (clear error otherwise)."""
    node = _get(meta, files, name, *keys)
    where = ".".join(map(str, keys))
    if not isinstance(node, list) or len(node) != length:
        raise InputError(files.label(name), f"'{where}' must be a list of {length} numbers")
    if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in node):
        raise InputError(files.label(name), f"'{where}' holds a value that is not a number")
    out = np.asarray(node, dtype=np.float64)
    if not (np.all(np.isfinite(out)) and np.all(np.abs(out) <= _MAX_META_VALUE)):
        raise InputError(files.label(name), f"'{where}' holds a non-finite or out-of-range value")
    return out


def _file_name(meta, files, name, *keys) -> str:
    node = _get(meta, files, name, *keys)
    if not isinstance(node, str) or not node:
        raise InputError(files.label(name), f"'{'.'.join(map(str, keys))}' must be a file name")
    return node


def _codebook(meta, files, name, key) -> np.ndarray:
    return _numbers(meta, files, name, key, "codebook", length=256).astype(np.float32)


def _decode_quats(px: np.ndarray) -> np.ndarray:
    """(N, 4) uint8 smallest-three codes -> (N, 4) float64 unit quaternions (w, x, y, z)."""
    n = len(px)
    small = (px[:, :3].astype(np.float64) / 255.0 * 2.0 - 1.0) / _SQRT2
    tag = px[:, 3].astype(np.int64) - 252
    valid = (tag >= 0) & (tag <= 3)
    largest = np.where(valid, tag, 0)
    # column of (w, x, y, z) receiving each of the three stored values, per largest-component tag
    slots = np.array([[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]])[largest]
    q = np.zeros((n, 4))
    rows = np.arange(n)[:, None]
    q[rows, slots] = small
    q[np.arange(n), largest] = np.sqrt(np.maximum(0.0, 1.0 - (small * small).sum(1)))
    q[~valid] = (1.0, 0.0, 0.0, 0.0)
    return q


def decode_means(q16: np.ndarray, mins: np.ndarray, maxs: np.ndarray) -> np.ndarray:
    """Positions (float64) of 16-bit codes (module docstring): the lerp, then ``sign(v)·(e^|v| − 1)``."""
    mins, maxs = np.asarray(mins, np.float64), np.asarray(maxs, np.float64)
    span = np.where(maxs - mins == 0, 1.0, maxs - mins)
    v = mins + span * (np.asarray(q16, np.float64) / 65535.0)
    with np.errstate(over="ignore"):
        return np.sign(v) * np.expm1(np.abs(v))


def _read_meta_file(files: SogFiles, name: str) -> GaussianScene:
    meta = files.json(name)
    if meta.get("version") != 2:
        raise InputError(files.label(name), f"unsupported SOG version {meta.get('version')!r} (only version 2)")
    count = _get(meta, files, name, "count")
    if not isinstance(count, int) or isinstance(count, bool) or not 0 <= count <= _MAX_COUNT:
        raise InputError(files.label(name), f"bad SOG count {count!r} (expected an integer 0..{_MAX_COUNT})")
    folder = posixpath.dirname(name)  # image names are relative to their meta.json

    def img(*keys) -> np.ndarray:
        return files.image(posixpath.join(folder, _file_name(meta, files, name, *keys)), count).reshape(-1, 4)[:count]

    # means: 16-bit lerp of the log-transformed positions
    lo, hi = img("means", "files", 0), img("means", "files", 1)
    q16 = lo[:, :3].astype(np.float64) + 256.0 * hi[:, :3]
    mins = _numbers(meta, files, name, "means", "mins", length=3)
    maxs = _numbers(meta, files, name, "means", "maxs", length=3)
    means = decode_means(q16, mins, maxs)
    if not np.all(np.isfinite(means.astype(np.float32))):
        raise InputError(files.label(name), "'means.mins/maxs' decode to positions outside float32 range")

    quats = _decode_quats(img("quats", "files", 0))
    scales_log = _codebook(meta, files, name, "scales")[img("scales", "files", 0)[:, :3]]
    sh0 = img("sh0", "files", 0)
    sh_dc = _codebook(meta, files, name, "sh0")[sh0[:, :3]]
    alpha = np.clip(sh0[:, 3].astype(np.float64) / 255.0, _OPACITY_EPS, 1.0 - _OPACITY_EPS)
    opacity_logit = np.log(alpha / (1.0 - alpha))
    sh_rest = np.zeros((count, 0, 3), np.float32)
    if meta.get("shN"):
        sh_rest = _decode_sh_rest(meta, files, name, count, folder)
    return GaussianScene.from_arrays(means, scales_log, quats, opacity_logit, sh_dc, sh_rest)


def _decode_sh_rest(meta: dict, files: SogFiles, name: str, count: int, folder: str) -> np.ndarray:
    bands = _get(meta, files, name, "shN", "bands")
    if bands not in (1, 2, 3):
        raise InputError(files.label(name), f"'shN.bands' is {bands!r}, expected 1, 2 or 3")
    k = SH_REST_COUNT[bands]
    palette = _get(meta, files, name, "shN", "count")
    if not isinstance(palette, int) or isinstance(palette, bool) or not 0 < palette <= 65536:
        raise InputError(files.label(name), f"'shN.count' is {palette!r}, expected 1..65536 palette entries")
    book = _codebook(meta, files, name, "shN")
    cent_name, label_name = (posixpath.join(folder, _file_name(meta, files, name, "shN", "files", i)) for i in (0, 1))
    cent = files.image(cent_name, None, pixels=64 * k * -(-palette // 64))
    if cent.shape[1] != 64 * k or cent.shape[0] * 64 < palette:
        raise InputError(files.label(cent_name), f"SH centroid image is {cent.shape[1]}x{cent.shape[0]}; "
                                                 f"expected width {64 * k} and room for {palette} entries")
    # (rows, 64 entries, K coefficients, RGBA) -> palette entry p = row*64 + column
    entries = cent.reshape(cent.shape[0], 64, k, 4).reshape(-1, k, 4)[:palette, :, :3]
    lab = files.image(label_name, count).reshape(-1, 4)[:count]
    labels = lab[:, 0].astype(np.int64) | (lab[:, 1].astype(np.int64) << 8)
    # decoded palette plus one zero entry that every out-of-palette label points at
    table = np.concatenate([book[entries], np.zeros((1, k, 3), np.float32)])
    return table[np.minimum(labels, palette)]


def concat_scenes(scenes: list[GaussianScene]) -> GaussianScene:
    """Rows of all scenes in order (same SH degree, no extras)."""
    cat = lambda attr: np.concatenate([getattr(s, attr) for s in scenes])
    return GaussianScene(cat("means"), cat("scales_log"), cat("quats"), cat("opacity_logit"),
                         cat("sh_dc"), cat("sh_rest"))


def lod_levels(path: str | Path) -> int | None:
    """Number of LOD levels of a ``lod-meta.json`` set; None for a single SOG (no levels)."""
    files, meta_name, is_lod = _open(Path(path))
    with files:
        return _levels(files.json(meta_name), files, meta_name) if is_lod else None


def _levels(meta: dict, files: SogFiles, name: str) -> int:
    levels = _get(meta, files, name, "lodLevels")
    if not _is_int(levels) or not 1 <= levels <= _MAX_LOD_LEVELS:
        raise InputError(files.label(name), f"bad lodLevels {levels!r} (expected an integer 1..{_MAX_LOD_LEVELS})")
    return levels


def _is_int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _lod_refs(meta: dict, files: SogFiles, name: str, level: int) -> dict[int, list[tuple[int, int]]]:
    """{file index: [(offset, count)]} of one level; every reference checked (module docstring)."""
    refs: dict[int, list[tuple[int, int]]] = {}
    stack = [_get(meta, files, name, "tree")]
    seen = 0
    while stack:
        node = stack.pop()
        seen += 1
        if seen > _MAX_TREE_NODES:
            raise InputError(files.label(name), f"'tree' has more than {_MAX_TREE_NODES:,} nodes")
        if not isinstance(node, dict):
            raise InputError(files.label(name), "bad 'tree' node in lod-meta.json (expected an object)")
        lods = node.get("lods") or {}
        if not isinstance(lods, dict):
            raise InputError(files.label(name), f"bad 'lods' {str(lods)[:60]} in a 'tree' node (expected an object "
                                                "of level -> {file, offset, count})")
        ref = lods.get(str(level))
        if ref is not None:
            if not isinstance(ref, dict) or not all(_is_int(ref.get(k)) for k in ("file", "offset", "count")):
                raise InputError(files.label(name), f"bad LOD reference {str(ref)[:80]} (file, offset and count must "
                                                    "be integers)")
            if ref["offset"] < 0 or ref["count"] < 0 or ref["file"] < 0:
                raise InputError(files.label(name), f"bad LOD reference {ref} (negative file, offset or count)")
            if ref["count"]:
                refs.setdefault(ref["file"], []).append((ref["offset"], ref["count"]))
        children = node.get("children") or []
        if not isinstance(children, list):
            raise InputError(files.label(name), "bad 'children' in a 'tree' node (expected a list)")
        stack.extend(children)
    for file_index, ranges in refs.items():
        ranges.sort()
        for (o1, c1), (o2, c2) in zip(ranges, ranges[1:]):
            if o2 < o1 + c1:
                raise InputError(files.label(name), f"LOD level {level}: references to file {file_index} overlap "
                                                    f"(rows {o1}..{o1 + c1} and {o2}..{o2 + c2}); each splat may "
                                                    "be referenced once")
    return refs


def _read_lod_level(files: SogFiles, name: str, meta: dict, level: int) -> GaussianScene:
    filenames = _get(meta, files, name, "filenames")
    if not isinstance(filenames, list) or not all(isinstance(f, str) and f for f in filenames):
        raise InputError(files.label(name), "'filenames' must be a list of file names")
    parts = []
    for file_index, ranges in sorted(_lod_refs(meta, files, name, level).items()):
        if not 0 <= file_index < len(filenames):
            raise InputError(files.label(name), f"LOD reference to file {file_index}, only {len(filenames)} listed")
        scene = _read_meta_file(files, filenames[file_index])
        for offset, count in ranges:
            if offset + count > len(scene):
                raise InputError(files.label(filenames[file_index]),
                                 f"LOD rows {offset}..{offset + count} exceed its {len(scene)} splats")
        rows = np.concatenate([np.arange(o, o + c) for o, c in ranges])
        whole_file = len(rows) == len(scene) and (rows == np.arange(len(scene))).all()
        parts.append(scene if whole_file else scene.subset(rows))
    if not parts:
        raise InputError(files.label(name), f"LOD level {level} references no splats")
    return parts[0] if len(parts) == 1 else concat_scenes(parts)


def _open(path: Path) -> tuple[SogFiles, str, bool]:
    """(file access, metadata file name, whether it is a lod-meta.json)."""
    if path.is_dir():
        for meta_name, is_lod in (("lod-meta.json", True), ("meta.json", False)):
            if (path / meta_name).is_file():
                return SogFiles(path, top=meta_name), meta_name, is_lod
        raise InputError(path, "folder holds neither lod-meta.json nor meta.json (not a SOG scene)")
    if path.suffix.lower() == ".sog":
        try:
            return SogFiles(path.parent, path), "meta.json", False
        except zipfile.BadZipFile:
            raise InputError(path, "not a valid .sog zip bundle") from None
    return SogFiles(path.parent, top=path.name), path.name, path.name.endswith("lod-meta.json")


def read_sog(path: str | Path, lod: int | str | None = None) -> GaussianScene:
    """Read a SOG scene; ``lod`` selects a level of a LOD set (None: 0, ``"all"``: every level)."""
    path = Path(path)
    files, meta_name, is_lod = _open(path)
    with files:
        if not is_lod:
            if lod not in (None, 0):
                raise InputError(path, f"has no LOD levels (asked for level {lod})")
            return _read_meta_file(files, meta_name)
        return _read_lod_set(path, files, meta_name, lod)


def _read_lod_set(path: Path, files: SogFiles, meta_name: str, lod) -> GaussianScene:
    meta = files.json(meta_name)
    levels = _levels(meta, files, meta_name)
    if lod == "all":
        return concat_scenes([_read_lod_level(files, meta_name, meta, level) for level in range(levels)])
    level = 0 if lod is None else lod
    if not isinstance(level, int) or not 0 <= level < levels:
        raise InputError(path, f"LOD level {lod!r} does not exist (levels 0..{levels - 1} or 'all')")
    return _read_lod_level(files, meta_name, meta, level)
