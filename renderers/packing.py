"""A scene packed for one camera, as the GL renderer draws it: the projected splats' instance
records, depth-sorted front to back (:func:`pack_instances`), and any subset of them
(:meth:`PackedView.kept`). See :mod:`renderers.gl` for what the records mean to the shaders."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from renderers.arrays import ops_for


@dataclass(frozen=True)
class PackedView:
    """A scene packed for one camera, ready to draw: the instance records ``(M, 12)`` of its drawable
    splats front to back (:func:`pack_instances`) and each one's index in the scene (``ids``)."""

    records: np.ndarray
    ids: np.ndarray
    width: int
    height: int

    def kept(self, keep: np.ndarray) -> PackedView:
        """The records of the splats with ``keep[id]`` (bool, one per scene splat), in the same order.

        Exactly what ``scene.subset(keep)`` packs to: a splat's record depends on that splat alone
        (:mod:`renderers.projection`), and the depth sort is stable with ties in scene order, so
        removing splats leaves the others' order as sorting the subset gives it.
        """
        sel = np.asarray(keep, bool)[self.ids]
        return PackedView(self.records[sel], self.ids[sel], self.width, self.height)


def pack_instances(projected) -> PackedView:
    """Depth-sorted (front to back) float32 instance records ``(M, 12)`` for the shaders.

    Columns: ``mean_x, mean_y, o, K, a, b, c, ac − b², r, g, b, radius`` with ``K = 2 ln(255 o)``.
    Splats with ``o < 1/255`` are left out (exact: they never pass the α test). Computed in the
    projection's library and on its device (one stable sort, one row gather), then copied to the
    host with one wait for the device (records and ids, :meth:`renderers.arrays.TorchOps.to_host`).
    """
    ops = ops_for(projected.opacities)
    xp = ops.lib
    f32 = lambda t: ops.cast(ops.detach(t), ops.float32)
    op = f32(projected.opacities).reshape(-1, 1)
    conics = f32(projected.conics)
    c64 = ops.cast(conics, ops.float64)
    det = ops.cast(xp.clip(c64[:, 0] * c64[:, 2] - c64[:, 1] * c64[:, 1], 1e-30, None), ops.float32)
    packed = xp.concatenate(
        [f32(projected.means2d), op, 2.0 * xp.log(255.0 * op), conics, det[:, None],
         f32(projected.colors), f32(projected.radii).reshape(-1, 1)],
        1,
    )
    keep = ops.flatnonzero(op[:, 0] >= 1.0 / 255.0)
    order = keep[ops.argsort_stable(f32(projected.depths).reshape(-1)[keep])]
    records, ids = ops.to_host(packed[order], projected.ids[order])
    return PackedView(records, ids, int(projected.width), int(projected.height))
