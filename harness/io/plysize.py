"""The exact size of the ``.ply`` the harness writes, without writing it: the rate of a rate point.

:func:`harness.io.ply.write_ply` writes a text header (``ply``, the preamble comments, ``format
binary_little_endian 1.0``, the other comments, ``element vertex N``, one ``property`` line per
column, ``end_header``, each ended by ``\\n``) followed by N fixed-size binary rows. So

    bytes(N) = header_bytes(N) + N · row_bytes,   header_bytes(N) = base + len(str(N))

where ``base`` is the header's length without the count's digits and ``row_bytes`` the layout's
itemsize. Both depend only on the scene's columns and comments, so one model serves every pruned
subset of a scene (tests check it against real writes).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from harness.core.scene import GaussianScene


@dataclass(frozen=True)
class PlySize:
    base: int       # header bytes without the digits of the vertex count
    row: int        # bytes per splat

    def __call__(self, count: int) -> int:
        count = int(count)
        return self.base + len(str(count)) + count * self.row


def ply_size_model(scene: GaussianScene, *, comments=None, preamble=None) -> PlySize:
    """The size model of ``write_ply(scene.subset(...))`` (same comment defaults as ``write_ply``)."""
    from harness.io.ply import ply_header_bytes, ply_layout

    comments = scene.meta.comments if comments is None else comments
    preamble = scene.meta.preamble if preamble is None else preamble
    layout = ply_layout(scene)
    header = ply_header_bytes(layout, 0, comments, preamble)
    return PlySize(len(header) - 1, int(np.dtype(layout).itemsize))


def ply_size(scene: GaussianScene, count: int | None = None) -> int:
    """Bytes of the ``.ply`` :func:`~harness.io.ply.write_ply` writes for ``scene`` (or for any
    ``count`` of its rows)."""
    return ply_size_model(scene)(len(scene) if count is None else count)
