"""Scene writers, chosen by the output file's name: one table for ``convert``, ``prune`` and
:func:`harness.io.scenes.write_scene`, made of the writable formats' registrations
(:mod:`harness.io.formats`).

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


def writers() -> tuple[Writer, ...]:
    """The writable registered formats (:mod:`harness.io.formats`), longest ending first:
    ``x.compressed.ply`` is a compressed.ply, not a .ply."""
    from harness.io.formats import FORMATS

    out = [Writer(f.ending, f.label, f.loses, f.write) for f in FORMATS if f.write is not None]
    return tuple(sorted(out, key=lambda w: -len(w.ending)))


def endings() -> list[str]:
    """The writable endings, in registration order."""
    from harness.io.formats import FORMATS

    return [f.ending for f in FORMATS if f.write is not None]


def writer_for(path) -> Writer:
    """The writer a file name asks for; InputError naming the endings otherwise."""
    from harness.core.suggest import did_you_mean
    from harness.io.formats import FORMATS

    name = Path(path).name.lower()
    for w in writers():
        if name.endswith(w.ending):
            return w
    known = ", ".join(endings())
    for f in FORMATS:
        if f.write is None and name.endswith(f.endings):
            raise InputError(path, f"{f.short} is read but not written{f.not_written}; write one of {known}")
    suffix = Path(name).suffix
    hint = did_you_mean(suffix, endings()) if suffix else ""
    raise InputError(path, f"cannot write {suffix + ' files' if suffix else 'files without an extension'}{hint}; "
                           f"the output name picks the format and must end in one of {known}")


def write(scene: GaussianScene, path, **options) -> Writer:
    """Write ``scene`` in the format its name asks for (atomically); returns the writer used."""
    w = writer_for(path)
    w.write(scene, Path(path), **options)
    return w
