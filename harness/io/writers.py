"""Scene writers, chosen by the output file's name: one table for ``convert``, ``prune`` and
:func:`harness.io.scenes.write_scene`.

=================  =====================================  ==========================================
name ends with     format                                  what is lost
=================  =====================================  ==========================================
``.compressed.ply``  PlayCanvas compressed.ply              quantised (11/10/11-bit chunks, 8-bit SH),
                                                           Morton row order, extras dropped
``.ply``           INRIA 3DGS .ply                         nothing (extras and comments kept)
``.splat``         antimatter15 .splat                     SH beyond degree 0, 8-bit colour/rotation
``.spz``           Niantic .spz (v4; v2/v3 on request)     quantised (12-bit fixed point, 8-bit rest)
=================  =====================================  ==========================================

SOG (``.sog``, ``meta.json``) is read but not written: its scale/colour codebooks and SH palette
are k-means clusterings the format leaves to the writer (splat-transform's GPU k-means), so no
writer here could reproduce a reference encoding, and a lossless-WebP encoder of our own would be a
second, unverified quantiser; ``splat-transform in.ply out.sog`` writes it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from harness.core.errors import InputError
from harness.core.scene import GaussianScene


@dataclass(frozen=True)
class Writer:
    ending: str                                   # the name's ending that selects it
    label: str                                    # what people call the format
    loses: str                                    # "" when lossless
    write: Callable[..., None]                    # write(scene, path, **options)


def _ply(scene, path, *, comments=None, sibr_layout=False, **_):
    from harness.io.ply import write_ply

    write_ply(scene, path, comments=comments, sibr_layout=sibr_layout)


def _compressed_ply(scene, path, *, comments=None, **_):
    from harness.io.compressed_ply import write_compressed_ply

    write_compressed_ply(scene, path, comments=comments)


def _splat(scene, path, **_):
    from harness.io.splat import write_splat

    write_splat(scene, path)


def _spz(scene, path, *, spz_version=None, **_):
    from harness.io.spz_write import DEFAULT_VERSION, write_spz

    write_spz(scene, path, spz_version or DEFAULT_VERSION)


#: longest ending first: ``x.compressed.ply`` is a compressed.ply, not a .ply
WRITERS = (
    Writer(".compressed.ply", "PlayCanvas compressed.ply", "quantised, Morton-reordered, extra properties dropped",
           _compressed_ply),
    Writer(".ply", "INRIA 3DGS .ply", "", _ply),
    Writer(".splat", "antimatter15 .splat", "SH degree > 0 dropped, 8-bit colour, opacity and rotation", _splat),
    Writer(".spz", "Niantic .spz", "quantised (12-bit fixed-point positions, 8-bit scales/colour/opacity, "
           "4-5-bit SH), extra properties dropped", _spz),
)
_NOT_WRITTEN = {".sog": "SOG", "meta.json": "SOG", ".ksplat": ".ksplat"}


def endings() -> list[str]:
    return [w.ending for w in WRITERS]


def writer_for(path) -> Writer:
    """The writer a file name asks for; InputError naming the endings otherwise."""
    from harness.core.suggest import did_you_mean

    name = Path(path).name.lower()
    for w in WRITERS:
        if name.endswith(w.ending):
            return w
    known = ", ".join(endings())
    for ending, what in _NOT_WRITTEN.items():
        if name.endswith(ending):
            why = " (see harness/io/writers.py; splat-transform writes it)" if what == "SOG" else ""
            raise InputError(path, f"{what} is read but not written{why}; write one of {known}")
    suffix = Path(name).suffix
    hint = did_you_mean(suffix, endings()) if suffix else ""
    raise InputError(path, f"cannot write {suffix + ' files' if suffix else 'files without an extension'}{hint}; "
                           f"the output name picks the format and must end in one of {known}")


def write(scene: GaussianScene, path, **options) -> Writer:
    """Write ``scene`` in the format its name asks for (atomically); returns the writer used."""
    w = writer_for(path)
    w.write(scene, Path(path), **options)
    return w
