"""MPEG GSC content folders: per-frame PLYs and their cameras, in the layouts MPEG distributes.

A *sequence folder* is recognised by the first layout that matches (frames sorted by name):

==========================================  ==================================================
frames                                      cameras (first found)
==========================================  ==================================================
``track/*.ply`` (``m71763_<seq>_stable``:   ``colmap_data/frame000/sparse[/0]`` (COLMAP, text or
``track/frame000.ply`` ...)                 binary), ``colmap_data/<first>/sparse``, ``colmap_SFM``,
``plys/*.ply`` (``plys/frame000.ply``)      ``sparse``, ``cameras/`` (COLMAP, ``cameras.json`` or
``frames/*.ply`` (this harness's layout)    ``transforms.json``), the folder itself (``cameras.txt``
``*.ply`` in the folder itself              + ``images.txt``, ``cameras.json``); else the
                                            ``camera_position`` lines of the first frame's header
==========================================  ==================================================

(MPEG GSC CTC content: ``m71763_{bartender,breakfast,cinema}_stable/track/frame%03d.ply`` with
``colmap_data/frame000/sparse/``; other deliveries use ``plys/`` or PLYs beside ``cameras.txt`` /
``images.txt``.) The first frame's cameras serve every frame, as in MPEG's scripts.

Cameras are used as the metric tool renders them (:func:`tool_cameras`): at the content's native
size (COLMAP's width × height; for header lines, the given size, else their size line, else the
CTC's 1920×1080), principal point at the image centre, focal.y on both axes.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from harness.core.cameras import Camera
from harness.core.errors import InputError

FRAME_DIRS = ("track", "plys", "frames", ".")
#: the CTC's image size, for header camera lines that carry none
CTC_SIZE = (1920, 1080)


@dataclass(frozen=True)
class Sequence:
    root: Path
    layout: str              # the frames folder relative to root ("track", "plys", "frames", ".")
    frames: tuple[Path, ...]
    cameras: Path | None     # a COLMAP model folder or a camera file; None: the first frame's header

    @property
    def camera_source(self) -> str:
        return str(self.cameras) if self.cameras is not None else f"{self.frames[0]} (camera_position lines)"


def _camera_location(root: Path) -> Path | None:
    from harness.io.colmap import find_colmap_model

    candidates = [root / "colmap_data" / "frame000", root / "colmap_data" / "frame_0000"]
    colmap_data = root / "colmap_data"
    if colmap_data.is_dir():
        candidates += sorted(p for p in colmap_data.iterdir() if p.is_dir())
    candidates += [root / "colmap_SFM", root / "sparse", root / "cameras", root]
    for c in candidates:
        if c.is_dir():
            model = find_colmap_model(c)
            if model is not None:
                return model
            for name in ("cameras.json", "transforms.json"):
                if (c / name).is_file():
                    return c / name
    return None


def find_sequence(root: str | Path) -> tuple[Sequence | None, str | None]:
    """(the sequence in ``root``, None) or (None, why not) — absent content is a reason, not an error."""
    root = Path(root)
    if not root.is_dir():
        return None, f"sequence folder not found: {root}"
    for sub in FRAME_DIRS:
        d = root / sub
        frames = tuple(sorted(p for p in d.glob("*.ply") if p.is_file())) if d.is_dir() else ()
        if frames:
            return Sequence(root, sub, frames, _camera_location(root)), None
    return None, f"no frame PLYs in {root} (looked in {', '.join(s + '/' for s in FRAME_DIRS[:-1])} and the folder)"


def tool_cameras(cams: list[Camera]) -> list[Camera]:
    """Cameras as the metric tool frames them: same pose and size, principal point at the centre,
    focal.y on both axes (``K = [[f_y, 0, W/2], [0, f_y, H/2]]``)."""
    return [Camera(c.world_to_cam, c.fy, c.fy, c.width / 2.0, c.height / 2.0, c.width, c.height, c.name)
            for c in cams]


def sequence_cameras(seq: Sequence, width: int | None = None, height: int | None = None) -> list[Camera]:
    """The sequence's cameras (every one, file order) as the tool renders them; header lines take
    ``width × height`` (else their size line, else :data:`CTC_SIZE`)."""
    from harness.io.cameras import load_cameras, read_ply_cameras
    from harness.io.ply import read_ply_header

    if seq.cameras is not None:
        cams = load_cameras(seq.cameras)
    else:
        header = read_ply_header(seq.frames[0])
        has_size = any(
            c.split(None, 1)[0:1] == ["camera_position_resolution"] for c in header.preamble + header.comments
        )
        w, h = (width, height) if width and height else ((None, None) if has_size else CTC_SIZE)
        cams = read_ply_cameras(seq.frames[0], w, h)
        if not cams:
            raise InputError(seq.root, "no cameras: no COLMAP model or camera file in the sequence folder and no "
                                       f"camera_position lines in {seq.frames[0].name}")
    return tool_cameras(cams)
