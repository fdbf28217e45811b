"""Scene formats, each registered once: how it is recognised, read, written, and which modules version it.

    register_format("splat", label="antimatter15 .splat", detect=probe_fn, read=read_fn,
                    modules=("harness.io.splat",), ending=".splat", write=write_fn, loses="SH beyond degree 0")

* ``detect(probe) -> str | None``: the name ``harness info`` prints when the file (or folder) is of
  this format, else None. Formats are asked in registration order (:func:`harness.io.detect.detect`);
  a :class:`Probe` holds the first bytes, the size and the name, and reads more only when asked.
* ``read(path, lod) -> GaussianScene``; ``lod_levels(path) -> int | None``: the levels of detail a
  file of a format that has them holds (SOG); formats without refuse a ``lod`` other than 0.
* ``modules``: the source that reading it runs. Every registered format's modules version the
  cached scene stages (:func:`reader_modules`, the run toolkit's ``reader_modules``), so an edit to
  a reader invalidates what it read — no list to keep in step by hand.
* ``ending`` (one name ending or several) + ``write(scene, path, **options)``: a writable format,
  chosen by the output's name (:mod:`harness.io.writers`). ``loses``: what writing a scene loses,
  text or ``loses(scene) -> str`` naming only what that scene has ("" when nothing: an SH-0 scene
  loses no SH). ``position_error(means) -> (N,)``: how far the format moves each centre (a
  quantising format), so that a writer moving splats by more than a stated bound because of
  outliers is reported (:mod:`harness.io.outliers`). ``outputs(path) -> [paths]``: every file
  written (default: the path). Names in ``endings`` that are read but not written are refused,
  with ``not_written`` saying why, even where a writable ending matches too (``lod-meta.json``
  ends in ``meta.json``).

Built-ins below; third-party packages add formats through the ``harness.formats`` entry-point group
(a module whose import calls :func:`register_format`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

from harness.core.registry import Registry
from harness.io import losses
from harness.io.safe import open_regular

ENTRY_POINT_GROUP = "harness.formats"
#: modules every read goes through, whatever the format (detection, validation, shared codecs)
COMMON_MODULES = ("harness.io.scenes", "harness.io.detect", "harness.io.formats", "harness.io.codecs")


@dataclass
class Probe:
    """What detection looks at: ``path`` (a file or folder), its first bytes ``head`` and ``size``
    (None for a folder), and the lower-case file ``name``; :meth:`read` for more bytes (bounded)."""

    path: Path
    head: bytes | None
    size: int | None

    @property
    def name(self) -> str:
        return self.path.name.lower()

    @property
    def is_dir(self) -> bool:
        return self.head is None

    def read(self, count: int) -> bytes:
        with open_regular(self.path, "scene", "scene file") as f:
            return f.read(count)

    @cached_property
    def ply_header(self):
        """The PLY header (read once, for every PLY-based format), None when the file is no PLY."""
        if self.head is None or self.head.split(b"\n", 1)[0].strip() != b"ply":
            return None
        from harness.io.ply import read_ply_header

        return read_ply_header(self.path)


@dataclass(frozen=True)
class SceneFormat:
    kind: str
    label: str
    detect: Callable[[Probe], str | None]
    read: Callable
    modules: tuple[str, ...]
    lod_levels: Callable | None = None
    #: the name endings that select this format's writer
    ending: tuple[str, ...] = ()
    write: Callable | None = None
    loses: str | Callable = ""
    #: names (endings) recognised but not written, and why not
    endings: tuple[str, ...] = ()
    short: str = ""
    not_written: str = ""
    position_error: Callable | None = None
    outputs: Callable | None = None


FORMATS: Registry[SceneFormat] = Registry("scene format", modules=(__name__,), group=ENTRY_POINT_GROUP)


def register_format(
    kind: str,
    *,
    label: str,
    detect: Callable,
    read: Callable,
    modules: tuple[str, ...],
    lod_levels: Callable | None = None,
    ending: str | tuple[str, ...] | None = None,
    write: Callable | None = None,
    loses: str | Callable = "",
    endings: tuple[str, ...] = (),
    short: str = "",
    not_written: str = "",
    position_error: Callable | None = None,
    outputs: Callable | None = None,
) -> SceneFormat:
    """Register scene format ``kind`` (module docstring)."""
    if (ending is None) != (write is None):
        raise ValueError(f"format {kind!r}: give both ending= and write=, or neither")
    written = () if ending is None else (ending,) if isinstance(ending, str) else tuple(ending)
    fmt = SceneFormat(kind, label, detect, read, tuple(modules), lod_levels, written, write, loses, tuple(endings),
                      short or label, not_written, position_error, outputs)
    same = lambda a, b: (a.kind, a.detect.__qualname__, a.read.__qualname__) == \
        (b.kind, b.detect.__qualname__, b.read.__qualname__)  # noqa: E731
    FORMATS.add(kind, fmt, same=same)
    return fmt


def reader_modules() -> tuple[str, ...]:
    """The modules whose source versions a cached scene read: the common path and every format's."""
    mods = list(COMMON_MODULES)
    for f in FORMATS:
        mods += [m for m in f.modules if m not in mods]
    return tuple(mods)


# --------------------------------------------------------------------------- built-in formats
def _compressed_ply(p: Probe) -> str | None:
    from harness.io import compressed_ply

    h = p.ply_header
    return compressed_ply.describe(h) if h is not None and compressed_ply.is_compressed_ply(h) else None


def _ply(p: Probe) -> str | None:
    h = p.ply_header
    return f"ply (INRIA 3DGS, {h.format.replace('_', ' ')})" if h is not None else None


def _read_ply(path, lod=None):
    from harness.io.ply import read_ply

    return read_ply(path)


def _write_ply(scene, path, *, comments=None, sibr_layout=False, **_):
    from harness.io.ply import write_ply

    write_ply(scene, path, comments=comments, sibr_layout=sibr_layout)


def _write_compressed_ply(scene, path, *, comments=None, **_):
    from harness.io.compressed_ply import write_compressed_ply

    write_compressed_ply(scene, path, comments=comments)


def _compressed_ply_error(means):
    from harness.io.compressed_ply import position_error

    return position_error(means)


def _spz(p: Probe) -> str | None:
    from harness.io import spz

    if p.is_dir:
        return None
    header = spz.probe(p.head if p.head[:2] != spz.GZIP_MAGIC else p.read(spz.PROBE_BYTES))
    return spz.describe(header) if header is not None else None


def _read_spz(path, lod=None):
    from harness.io.spz import read_spz

    return read_spz(path)


def _write_spz(scene, path, *, spz_version=None, **_):
    from harness.io.spz_write import DEFAULT_VERSION, write_spz

    write_spz(scene, path, DEFAULT_VERSION if spz_version is None else spz_version)


def _spz_error(means):
    from harness.io.spz_write import position_error

    return position_error(means)


def _zip_has_meta(path: Path) -> bool:
    import zipfile

    try:
        with zipfile.ZipFile(path) as z:
            return "meta.json" in z.namelist()
    except (zipfile.BadZipFile, OSError):
        return False


def _sog(p: Probe) -> str | None:
    if p.is_dir:
        if (p.path / "lod-meta.json").is_file() or (p.path / "meta.json").is_file():
            return "sog (PlayCanvas SOG folder)"
        return None
    if p.head[:4] == b"PK\x03\x04" and (p.name.endswith(".sog") or _zip_has_meta(p.path)):
        return "sog (PlayCanvas SOG bundle)"
    if p.name.endswith(("meta.json", "lod-meta.json")):
        return "sog (PlayCanvas SOG meta.json)"
    return None


def _read_sog(path, lod=None):
    from harness.io.sog import read_sog

    return read_sog(path, lod)


def _sog_levels(path):
    from harness.io.sog import lod_levels

    return lod_levels(path)


def _write_sog(scene, path, **_):
    from harness.io.sog_write import write_sog

    write_sog(scene, path)


def _sog_error(means):
    from harness.io.sog_write import position_error

    return position_error(means)


def _sog_outputs(path):
    from harness.io.sog_write import output_files

    return output_files(path)


def _ksplat(p: Probe) -> str | None:
    from harness.io import ksplat

    if p.is_dir:
        return None
    if p.name.endswith(".ksplat") and ksplat.looks_like_ksplat(p.head):
        header = ksplat.probe(p.path, p.size)
        return ksplat.describe(header) if header is not None else "ksplat (unreadable header)"
    header = ksplat.probe(p.path, p.size)
    return ksplat.describe(header) if header is not None and header.size == p.size else None


def _read_ksplat(path, lod=None):
    from harness.io.ksplat import read_ksplat

    return read_ksplat(path)


def _splat(p: Probe) -> str | None:
    if p.is_dir or not p.name.endswith(".splat") or p.head[:2] == b"\x1f\x8b":
        return None
    return "splat (antimatter15, 32-byte records)"


def _read_splat(path, lod=None):
    from harness.io.splat import read_splat

    return read_splat(path)


def _write_splat(scene, path, **_):
    from harness.io.splat import write_splat

    write_splat(scene, path)


register_format("compressed-ply", label="PlayCanvas compressed.ply", detect=_compressed_ply, read=_read_ply,
                modules=("harness.io.ply", "harness.io.compressed_ply"), ending=".compressed.ply",
                write=_write_compressed_ply, loses=losses.compressed_ply, position_error=_compressed_ply_error)
register_format("ply", label="INRIA 3DGS .ply", detect=_ply, read=_read_ply, modules=("harness.io.ply",),
                ending=".ply", write=_write_ply)
register_format("spz", label="Niantic .spz", detect=_spz, read=_read_spz, modules=("harness.io.spz",),
                ending=".spz", write=_write_spz, loses=losses.spz, position_error=_spz_error)
register_format("sog", label="PlayCanvas SOG", detect=_sog, read=_read_sog,
                modules=("harness.io.sog", "harness.io.sog_files"),
                lod_levels=_sog_levels, ending=(".sog", "meta.json"), write=_write_sog, loses=losses.sog,
                position_error=_sog_error, outputs=_sog_outputs, endings=("lod-meta.json",), short="streamed SOG",
                not_written=" (level-of-detail sets are not written; write one level as .sog or meta.json)")
register_format("ksplat", label="mkkellogg .ksplat", detect=_ksplat, read=_read_ksplat, modules=("harness.io.ksplat",),
                endings=(".ksplat",), short=".ksplat")
register_format("splat", label="antimatter15 .splat", detect=_splat, read=_read_splat, modules=("harness.io.splat",),
                ending=".splat", write=_write_splat, loses=losses.splat)
