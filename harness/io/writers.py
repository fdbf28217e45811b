"""Scene writers, chosen by the output file's name: one table for ``convert``, ``prune`` and
:func:`harness.io.scenes.write_scene`, made of the writable formats' registrations
(:mod:`harness.io.formats`).

=================  =====================================  ==========================================
name ends with     format                                  what is lost (:mod:`harness.io.losses`)
=================  =====================================  ==========================================
``.compressed.ply``  PlayCanvas compressed.ply              quantised (11/10/11-bit chunks, 8-bit SH),
                                                           Morton row order, extras dropped
``.ply``           INRIA 3DGS .ply                         nothing (extras and comments kept)
``.splat``         antimatter15 .splat                     SH beyond degree 0, 8-bit colour/rotation
``.spz``           Niantic .spz (v4; v2/v3 on request)     quantised (12-bit fixed point, 8-bit rest)
``.sog``           PlayCanvas SOG bundle (one zip)         quantised (16-bit log positions, 256-entry
``meta.json``      PlayCanvas SOG folder (+ WebP textures)  codebooks, k-means SH palette), Morton order
=================  =====================================  ==========================================

A lossy note names only what the scene being written has (no "SH dropped" for an SH-0 scene).
``lod-meta.json`` (a streamed SOG with levels of detail) is read but not written, nor is ``.ksplat``.
A writer that quantises positions declares how far it moves each centre; when splats far from the
others make it move the rest by more than a stated bound, :func:`write` reports it
(:mod:`harness.io.outliers`).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from harness.core.errors import InputError
from harness.core.scene import GaussianScene

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Writer:
    ending: str                                   # the name's ending that selects it
    label: str                                    # what people call the format
    write: Callable[..., None]                    # write(scene, path, **options)
    describe_losses: str | Callable = ""          # text, or scene -> text; "" when lossless
    position_error: Callable | None = None        # means -> (N,) distance each centre is moved
    outputs: Callable | None = None               # path -> every file written (default: the path)

    def loses(self, scene: GaussianScene) -> str:
        """What writing ``scene`` in this format loses ("" when nothing)."""
        return self.describe_losses(scene) if callable(self.describe_losses) else self.describe_losses

    def files(self, path) -> list[Path]:
        """Every file that writing ``path`` creates or replaces."""
        return list(self.outputs(Path(path))) if self.outputs else [Path(path)]


def writers() -> tuple[Writer, ...]:
    """The writable registered formats (:mod:`harness.io.formats`), one per name ending, longest
    ending first: ``x.compressed.ply`` is a compressed.ply, not a .ply."""
    from harness.io.formats import FORMATS

    out = []
    for f in FORMATS:
        if f.write is None:
            continue
        for ending in f.ending:
            label = f"{f.label} ({'bundle' if ending == '.sog' else 'folder'})" if f.kind == "sog" else f.label
            out.append(Writer(ending, label, f.write, f.loses, f.position_error, f.outputs))
    return tuple(sorted(out, key=lambda w: -len(w.ending)))


def endings() -> list[str]:
    """The writable endings, in registration order."""
    from harness.io.formats import FORMATS

    return [e for f in FORMATS if f.write is not None for e in f.ending]


def writer_for(path) -> Writer:
    """The writer a file name asks for; InputError naming the endings otherwise. The longest
    matching ending decides, so a name a format reads but does not write (``lod-meta.json``) is
    refused even though a writable ending (``meta.json``) matches it too."""
    from harness.core.suggest import did_you_mean
    from harness.io.formats import FORMATS

    name = Path(path).name.lower()
    known = ", ".join(endings())
    writable = next((w for w in writers() if name.endswith(w.ending)), None)
    for f in FORMATS:
        for ending in f.endings:
            if name.endswith(ending) and (writable is None or len(ending) > len(writable.ending)):
                raise InputError(path, f"{f.short} is read but not written{f.not_written}; write one of {known}")
    if writable is not None:
        return writable
    suffix = Path(name).suffix
    hint = did_you_mean(suffix, endings()) if suffix else ""
    raise InputError(path, f"cannot write {suffix + ' files' if suffix else 'files without an extension'}{hint}; "
                           f"the output name picks the format and must end in one of {known}")


def write(scene: GaussianScene, path, **options) -> Writer:
    """Write ``scene`` in the format its name asks for (atomically); returns the writer used. A
    writer that moves centres because of outliers is reported as a warning (module docstring)."""
    w = writer_for(path)
    w.write(scene, Path(path), **options)
    if w.position_error is not None:
        from harness.io.outliers import displacement_warning

        line = displacement_warning(path, scene.means, w.position_error)
        if line:
            log.warning("harness: warning: %s", line)
    return w
