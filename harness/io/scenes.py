"""One entry point for scenes: load by path or name, validate, write, describe.

Formats are recognised by content first (:mod:`harness.io.detect`): INRIA ``.ply``, PlayCanvas
``compressed.ply``, Niantic ``.spz`` (v1-4), mkkellogg ``.ksplat`` (levels 0-2), antimatter15
``.splat``, SOG (a folder with ``lod-meta.json`` or ``meta.json``, either JSON file, or a ``.sog``
bundle); anything else is "unsupported format: <what it looks like>". Named scenes
(``bonsai-7k``, ``playbot``, ...) resolve through :mod:`harness.io.datasets`. Written:
``.ply``, ``.compressed.ply``, ``.splat`` and ``.spz``, by the name's ending (:mod:`harness.io.writers`).

Validation after reading (every format):

* NaN/inf in any core array (means, scales, quats, opacity, SH): an :class:`InputError` naming the
  count and the first row, unless ``drop_nonfinite=True``, which removes those rows and reports
  the count in :class:`LoadResult` (and as a logging warning from :func:`load_scene`). Extra
  properties (normals ...) are carried, not checked: they do not affect rendering.
* zero-norm quaternions: always an error (the rotation is undefined; nothing is dropped silently).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from harness.core.errors import InputError
from harness.core.scene import GaussianScene, bounding_box, opacities, scales

log = logging.getLogger(__name__)


@dataclass
class LoadResult:
    scene: GaussianScene
    path: Path
    format: str           # a registered format (harness.io.formats): "ply" | "compressed-ply" | "spz" | ...
    lod: int | str | None  # the SOG level read (None for single-level formats)
    dropped_nonfinite: int = 0
    format_name: str = ""  # e.g. "spz v3 (gzip, SH degree 3)": what `harness info` prints


def scene_extent(path: Path) -> Path:
    """What reading the scene at ``path`` depends on: for a SOG scene named by its ``meta.json`` or
    ``lod-meta.json``, the folder (its textures and LOD files are read only from there:
    :func:`harness.io.safe.confined`); otherwise ``path`` itself (a file, a SOG folder, a bundle).
    Cache keys hash this, so editing one texture of such a scene changes its key."""
    path = Path(path)
    if path.name.lower().endswith("meta.json") and path.is_file():
        return path.parent
    return path


def check_scene(scene: GaussianScene, source, *, drop_nonfinite: bool = False) -> tuple[GaussianScene, int]:
    """Validate a freshly read scene (:func:`harness.core.validate.validate`); returns (scene, rows
    dropped for NaN/inf)."""
    from harness.core.validate import validate

    return validate(scene, source, drop_nonfinite=drop_nonfinite, hint="use --drop-nonfinite to drop them")


def read_scene(path_or_name, *, lod: int | str | None = None, drop_nonfinite: bool = False) -> LoadResult:
    """Read and validate a scene given by path or name (see module docstring)."""
    from harness.io.datasets import resolve_scene
    from harness.io.detect import detect
    from harness.io.formats import FORMATS

    path = resolve_scene(path_or_name)
    try:
        detected = detect(path)
        fmt = detected.kind
        spec = FORMATS.get(fmt)
        if spec.lod_levels is None and lod not in (None, 0):
            raise InputError(path, f"has no LOD levels (asked for level {lod})")
        scene = spec.read(path, lod)
        # the level read: of a format with levels, when this file has them (a SOG without lod-meta.json has none)
        lod = (0 if lod is None else lod) if spec.lod_levels is not None and spec.lod_levels(path) is not None \
            else None
    except IsADirectoryError:
        raise InputError(path, "is a folder, expected a file") from None
    except PermissionError:
        raise InputError(path, "permission denied") from None
    except OSError as err:
        raise InputError(path, f"cannot read: {err.strerror or err}") from None
    scene, dropped = check_scene(scene, path, drop_nonfinite=drop_nonfinite)
    scene = scene.with_meta(source=str(path), format=fmt)
    return LoadResult(scene, path, fmt, lod, dropped, detected.name)


def load_scene(path_or_name, *, lod: int | str | None = None, drop_nonfinite: bool = False) -> GaussianScene:
    """The validated scene; dropped NaN/inf rows (only with ``drop_nonfinite``) are logged."""
    result = read_scene(path_or_name, lod=lod, drop_nonfinite=drop_nonfinite)
    if result.dropped_nonfinite:
        log.warning("%s: dropped %d splats with NaN/inf values", result.path, result.dropped_nonfinite)
    return result.scene


def write_scene(scene: GaussianScene, path, *, comments=None, sibr_layout: bool = False,
                spz_version: int | None = None) -> Path:
    """Write ``scene`` atomically in the format its name asks for (:mod:`harness.io.writers`:
    ``.ply`` lossless, ``.compressed.ply``, ``.splat``, ``.spz``, SOG ``.sog``/``meta.json`` lossy);
    returns the path.

    A ``.ply`` or ``.compressed.ply`` keeps the scene's header comments (``scene.meta``; ``comments``
    replaces those after the ``format`` line); ``sibr_layout`` applies to ``.ply``, see
    :mod:`harness.io.ply`; ``spz_version`` to ``.spz`` (default 4).
    """
    from harness.io.writers import write, writer_for

    path = Path(path)
    writer_for(path)
    if not path.parent.is_dir():
        raise InputError(path, "output folder does not exist")
    try:
        write(scene, path, comments=comments, sibr_layout=sibr_layout, spz_version=spz_version)
    except OSError as err:  # permission, read-only or full disk: the temp file is already gone
        raise InputError(path, f"cannot write: {err.strerror or err}") from None
    return path


def scene_files(path) -> list[Path]:
    """Every file a scene at ``path`` consists of: a folder's files, a SOG ``meta.json`` and the
    textures it names, a ``lod-meta.json`` and its folder's files, or the file itself."""
    p = Path(path)
    if p.is_dir() or (p.name.endswith("lod-meta.json") and p.is_file()):
        return sorted(f for f in (p if p.is_dir() else p.parent).rglob("*") if f.is_file())
    if p.name.endswith("meta.json") and p.is_file():
        from harness.io.sog_files import named_files

        return [p] + [f for f in named_files(p) if f.is_file()]
    return [p]


def _stats(x: np.ndarray) -> dict:
    x = np.asarray(x, np.float64).ravel()
    if x.size == 0:
        return {"min": None, "max": None, "mean": None, "median": None}
    return {"min": float(x.min()), "max": float(x.max()), "mean": float(x.mean()), "median": float(np.median(x))}


def describe_scene(scene: GaussianScene, path=None, *, fmt: str | None = None, lod=None,
                   format_name: str | None = None) -> dict:
    """The facts ``harness info`` prints: counts, SH degree, bounding box, opacity/scale stats, memory.

    ``memory_bytes`` is the scene's arrays in memory; ``file_bytes`` is everything under ``path``
    on disk (for a SOG folder: all its LOD levels).
    """
    lo, hi, diag = bounding_box(scene)
    info = {
        "path": None if path is None else str(path),
        "format": fmt,
        "format_name": format_name or fmt,
        "lod": lod,
        "splats": len(scene),
        "sh_degree": scene.sh_degree,
        "bbox_min": [float(v) for v in lo],
        "bbox_max": [float(v) for v in hi],
        "bbox_diagonal": diag,
        "opacity": _stats(opacities(scene)),
        "scale": _stats(scales(scene)),
        "scale_max_axis": _stats(scales(scene).max(axis=1) if len(scene) else np.zeros(0)),
        "extra_properties": list(scene.extra),
        "memory_bytes": scene.nbytes,
    }
    if path is not None:
        info["file_bytes"] = int(sum(f.stat().st_size for f in scene_files(path)))
    return info
