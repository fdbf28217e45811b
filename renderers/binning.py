"""Binning for the reference rasterizer (:mod:`renderers.reference`): every (tile, splat) pair whose
footprint touches the tile, listed tile by tile with each tile's splats front to back (splats sorted
by view depth, stable, ties by scene index; the list then stably sorted by tile)."""

from __future__ import annotations

from dataclasses import dataclass

import torch

from renderers.projection import TILE, Projected, tile_rects

FOOTPRINTS = ("box", "tile")


@dataclass
class Bins:
    entries: torch.Tensor  # (E,) index into the Projected arrays, grouped by tile, depth order inside
    start: torch.Tensor  # (n_tiles,) first entry of each tile
    count: torch.Tensor  # (n_tiles,) number of entries
    gx: int
    gy: int


def bin_splats(proj: Projected, footprint: str = "box", tile: int = TILE) -> Bins:
    """Tile lists in depth order. ``box``: tiles containing a pixel centre of the ±r box;
    ``tile``: graphdeco's ``getRect`` rectangle (16-px tiles only)."""
    w, h = proj.width, proj.height
    gx, gy = (w + tile - 1) // tile, (h + tile - 1) // tile
    dev = proj.means2d.device
    order = torch.sort(proj.depths.detach(), stable=True).indices
    m2d, r = proj.means2d.detach()[order], proj.radii.detach()[order]
    if footprint == "tile":
        if tile != TILE:
            raise ValueError("footprint='tile' reproduces graphdeco and needs 16-px tiles")
        x0, x1, y0, y1 = tile_rects(m2d, r, w, h)
    elif footprint == "box":
        def rng(c, size):
            lo = torch.ceil(c - r).clamp(min=0)
            hi = torch.floor(c + r).clamp(max=size - 1)
            empty = lo > hi
            a = torch.div(lo.clamp(max=size - 1), tile, rounding_mode="floor").long()
            b = torch.div(hi.clamp(min=0), tile, rounding_mode="floor").long() + 1
            return a, torch.where(empty, a, b)

        x0, x1 = rng(m2d[:, 0], w)
        y0, y1 = rng(m2d[:, 1], h)
    else:
        raise ValueError(f"footprint must be one of {FOOTPRINTS}, got {footprint!r}")
    wx = (x1 - x0).clamp(min=0)
    n_per = wx * (y1 - y0).clamp(min=0)
    total = int(n_per.sum())
    splat = torch.repeat_interleave(torch.arange(len(order), device=dev), n_per)
    first = torch.cumsum(n_per, 0) - n_per
    off = torch.arange(total, device=dev) - first[splat]
    wx_s = wx[splat]
    tiles = (y0[splat] + torch.div(off, wx_s, rounding_mode="floor")) * gx + x0[splat] + off % wx_s
    tiles, perm = torch.sort(tiles, stable=True)
    entries = order[splat[perm]]
    count = torch.bincount(tiles, minlength=gx * gy)
    start = torch.cumsum(count, 0) - count
    return Bins(entries, start, count, gx, gy)
