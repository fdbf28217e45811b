"""MPEG camera lines in PLY headers: gsTools' ``camera_position`` comments, read and written.

The syntax (gsTools ``util/pointcloud.hpp`` writer, mpeg-gsc-metrics ``util/pointcloud.hpp``
reader; ISO/IEC, BSD; github.com/little-little-point-cloud-group/gscem @ c4a0c1cae569…,
``submodules/mpeg-gsc-tools/gsTools/source`` and ``submodules/mpeg-gsc-metrics/source``)::

    ply
    comment camera_position_header imageId cameraId pos.x pos.y pos.z quat.w quat.x quat.y quat.z focal.x focal.y name
    comment camera_position  <imageId> <cameraId> <pos.xyz> <quat.wxyz> <focal.xy> <name>
    ...
    format binary_little_endian 1.0

one line per view, **before** the ``format`` line (numbers ``%16.10f``, ids ``%8d``). The metric tool
reads a comment as a camera when it contains ``"camera_position "`` (trailing space: the
``_header`` line is skipped) and all twelve tokens parse (``ss >> ... >> el.name_``: the name is
mandatory and has no spaces); every such line is a viewpoint, in file order.

**Pose convention** (gsTools ``util/cameraPosition.hpp`` from COLMAP ``images.txt``:
``el.quaternion_ = glm::quat( qw, qx, qy, qz )`` — COLMAP's qvec as is — and
``el.position_ = -( glm::transpose( glm::mat3_cast( el.quaternion_ ) ) * glm::vec3( tx, ty, tz ) )``):

* ``quat`` (w, x, y, z) is COLMAP's **world-to-camera** rotation R(q) (Hamilton, = ``qvec2rotmat``);
* ``pos`` is the **camera centre** C = −R(q)ᵀ t in world coordinates;
* axes are OpenCV's (the tool's renderer: ``forward = Rᵀ·(0,0,1)``, ``up = Rᵀ·(0,−1,0)``), so
  ``world_to_cam = [[R(q), −R(q)·C], [0, 0, 0, 1]]`` (−R(q)·C is COLMAP's tvec);
* ``focal`` is in pixels; the principal point and image size are not stored: the tool renders a
  ``--width × --height`` window (default 1024×768; the CTC passes 1920×1080) with vertical FOV
  ``2·atan(H / (2·focal.y))`` and aspect W/H, i.e. ``K = [[f_y, 0, W/2], [0, f_y, H/2]]`` — focal.y
  on both axes (focal.x only enters its splat-covariance Jacobian). We read a line as that
  camera: ``fx = fy = focal.y``, ``cx = W/2``, ``cy = H/2``. The quaternion is normalised (COLMAP
  writes unit quaternions; gsTools does not re-normalise).

Image size: the caller's (``--width/--height``), else a ``camera_position_resolution W H`` comment
this harness writes beside the lines (the MPEG readers ignore it: it lacks ``"camera_position "``),
else the tool's default 1024×768. A malformed ``camera_position`` line is an :class:`InputError`.
"""

from __future__ import annotations

import math

import numpy as np

from harness.core.cameras import Camera
from harness.core.errors import InputError

TAG = "camera_position"
HEADER_TAG = "camera_position_header"
SIZE_TAG = "camera_position_resolution"
#: the metric tool's --width/--height defaults
TOOL_SIZE = (1024, 768)
_COLUMNS = ("imageId", "cameraId", "pos.x", "pos.y", "pos.z", "quat.w", "quat.x", "quat.y", "quat.z",
            "focal.x", "focal.y", "name")


def is_camera_comment(text: str) -> bool:
    """Is a comment text (after ``comment``) one of the gsTools camera lines (or their size line)?"""
    word = text.split(None, 1)[0] if text.strip() else ""
    return word in (TAG, HEADER_TAG, SIZE_TAG)


def _is_pose_line(text: str) -> bool:
    return text.split(None, 1)[0] == TAG if text.strip() else False


def rotmat(q) -> np.ndarray:
    """Rotation matrix of a unit quaternion (w, x, y, z), Hamilton convention (COLMAP qvec2rotmat)."""
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def quaternion(r: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z), w ≥ 0, of a rotation matrix (Shepperd's method)."""
    r = np.asarray(r, np.float64)
    t = np.trace(r)
    cases = [t, r[0, 0], r[1, 1], r[2, 2]]
    k = int(np.argmax(cases))
    if k == 0:
        s = 2.0 * math.sqrt(1.0 + t)
        q = [0.25 * s, (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s]
    else:
        i, j, m = [(0, 1, 2), (1, 2, 0), (2, 0, 1)][k - 1]
        s = 2.0 * math.sqrt(1.0 + r[i, i] - r[j, j] - r[m, m])
        q = [0.0] * 4
        q[0] = (r[m, j] - r[j, m]) / s
        q[1 + i] = 0.25 * s
        q[1 + j] = (r[j, i] + r[i, j]) / s
        q[1 + m] = (r[m, i] + r[i, m]) / s
    q = np.asarray(q)
    return q if q[0] >= 0 else -q


def camera_lines(cameras: list[Camera]) -> list[str]:
    """Comment texts (header, one ``camera_position`` line per camera, the size line) for the PLY
    preamble; :func:`harness.io.ply.write_ply` puts them before ``format`` wherever they are given.

    Raises ValueError for a camera the syntax cannot hold: a principal point off the image centre,
    cameras of different sizes, or (not representable either) fx ≠ fy beyond 1e-9 relative."""
    if not cameras:
        return []
    sizes = {(c.width, c.height) for c in cameras}
    if len(sizes) > 1:
        raise ValueError(f"camera_position lines hold one image size; these cameras have {sorted(sizes)}")
    head = f"{HEADER_TAG} {'imageId':>8} {'cameraId':>8}" + "".join(f" {c:>16}" for c in _COLUMNS[2:])
    out = [head]
    for i, cam in enumerate(cameras):
        if not (math.isclose(cam.cx, cam.width / 2.0, abs_tol=1e-9) and math.isclose(cam.cy, cam.height / 2.0,
                                                                                   abs_tol=1e-9)):
            raise ValueError(f"camera {cam.name or i!r}: principal point ({cam.cx}, {cam.cy}) is off the image "
                             "centre; camera_position lines assume the centre")
        if not math.isclose(cam.fx, cam.fy, rel_tol=1e-9):
            raise ValueError(f"camera {cam.name or i!r}: fx {cam.fx} != fy {cam.fy}; the metric tool projects "
                             "with focal.y on both axes")
        q = quaternion(cam.rotation)
        vals = [*cam.center, *q, cam.fx, cam.fy]
        name = "_".join((cam.name or f"view_{i:04d}").split())
        out.append(f"{TAG} {i + 1:>8d} {1:>8d}" + "".join(f" {v:16.10f}" for v in vals) + f" {name:>16}")
    w, h = sizes.pop()
    out.append(f"{SIZE_TAG} {w} {h}")
    return out


def _parse(text: str, width: int, height: int, source, number: int) -> Camera:
    tokens = text.split()[1:]
    if len(tokens) < 12:
        raise InputError(source, f"camera_position line {number} has {len(tokens)} of the 12 fields "
                                 f"({' '.join(_COLUMNS)}): {text[:100]!r}")
    try:
        int(tokens[0]), int(tokens[1])
        v = [float(t) for t in tokens[2:11]]
    except ValueError:
        raise InputError(source, f"camera_position line {number}: non-numeric field in {text[:100]!r}") from None
    if not all(math.isfinite(x) for x in v):
        raise InputError(source, f"camera_position line {number}: non-finite value in {text[:100]!r}")
    pos, q, (fx, fy) = np.array(v[0:3]), np.array(v[3:7]), v[7:9]
    norm = float(np.linalg.norm(q))
    if not abs(norm - 1.0) <= 1e-3:
        raise InputError(source, f"camera_position line {number}: quaternion norm {norm:.6g} is not 1")
    if fx <= 0 or fy <= 0:
        raise InputError(source, f"camera_position line {number}: focal lengths must be positive")
    r = rotmat(q / norm)
    m = np.eye(4)
    m[:3, :3] = r
    m[:3, 3] = -r @ pos
    return Camera(m, fy, fy, width / 2.0, height / 2.0, int(width), int(height), tokens[11])


def cameras_from_lines(comments, source, width: int | None = None, height: int | None = None) -> list[Camera]:
    """Cameras of the ``camera_position`` comment texts among ``comments`` (file order; others
    ignored). Size: ``width/height``, else the file's size line, else :data:`TOOL_SIZE`."""
    comments = list(comments)
    if width is None or height is None:
        size = [c.split()[1:3] for c in comments if c.split(None, 1)[0:1] == [SIZE_TAG]]
        try:
            w, h = (int(x) for x in size[-1]) if size else TOOL_SIZE
        except ValueError:
            raise InputError(source, f"bad {SIZE_TAG} line: {size[-1]}") from None
        width, height = width or w, height or h
    from harness.core.cameras import size_problem

    why = size_problem(width, height)
    if why:  # the size line of the file (or --width/--height): refused before any camera is made
        raise InputError(source, f"camera image size: {why}")
    lines = [c for c in comments if _is_pose_line(c)]
    return [_parse(c, width, height, source, i + 1) for i, c in enumerate(lines)]


def split_preamble(preamble, comments) -> tuple[list[str], list[str]]:
    """(preamble, comments) with every gsTools camera line moved before ``format``, where MPEG
    content and gsTools put them and where MPEG's parsers look for them; order kept."""
    comments = list(comments)
    moved = [c for c in comments if is_camera_comment(c)]
    return list(preamble) + moved, [c for c in comments if not is_camera_comment(c)]
