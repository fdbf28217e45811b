"""What writing a scene in a lossy format loses, said for that scene: ``convert`` and ``prune``
print it after ``lossy:``. Only what the scene has is named — an SH-0 scene loses no SH, a scene
without extra properties or header comments loses none — so a note never claims a loss that did
not happen; the quantisation of what every scene has (positions, colours ...) is always named.
"""

from __future__ import annotations

from harness.core.scene import GaussianScene


def _dropped(scene: GaussianScene, comments: bool = True) -> list[str]:
    """Extra properties (named) and, unless the format keeps them, header comments."""
    out = []
    if scene.extra:
        names = list(scene.extra)
        out.append(f"extra properties dropped ({', '.join(names[:4])}{', ...' if len(names) > 4 else ''})")
    if comments and scene.meta.all_comments:
        out.append("header comments dropped")
    return out


def _join(quantised: str, *rest: str) -> str:
    return ", ".join([quantised, *rest])


def compressed_ply(scene: GaussianScene) -> str:
    sh = ", 8-bit SH" if scene.sh_degree else ""
    return _join(f"quantised (11/10/11-bit positions and scales per 256-splat chunk, 8-bit colour and opacity, "
                 f"10-bit rotations{sh})", "rows in Morton order", *_dropped(scene, comments=False))


def spz(scene: GaussianScene) -> str:
    sh = ", 4-5-bit SH" if scene.sh_degree else ""
    return _join(f"quantised (12-bit fixed-point positions, 8-bit scales, colour and opacity{sh})", *_dropped(scene))


def splat(scene: GaussianScene) -> str:
    sh = [f"SH degree {scene.sh_degree} dropped"] if scene.sh_degree else []
    return _join("8-bit colour, opacity and rotation", *sh, *_dropped(scene))


def sog(scene: GaussianScene) -> str:
    sh = ", SH as a k-means palette" if scene.sh_degree else ""
    return _join(f"quantised (16-bit log positions, 256-entry scale and colour codebooks, 8-bit opacity and "
                 f"rotations{sh})", "rows in Morton order", *_dropped(scene))
