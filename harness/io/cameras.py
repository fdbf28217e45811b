"""Camera files -> ``list[Camera]`` (OpenCV axes, see :mod:`harness.core.cameras`), and writers.

Formats (:func:`load_cameras` dispatches on the path):

* **3DGS ``cameras.json``** (graphdeco ``camera_to_JSON``): a list of ``{id, img_name, width, height,
  position, rotation, fx, fy}`` where ``position`` is the camera centre C in world coordinates and
  ``rotation`` the 3×3 camera-to-world rotation (rows as nested lists, OpenCV axes). Hence
  ``R_w2c = rotationᵀ`` and ``t = −R_w2c C``. The format has no principal point: 3DGS assumes the
  image centre, so ``cx = width/2, cy = height/2`` unless optional ``cx``/``cy`` keys are present
  (our writer adds them only when the principal point is off-centre; graphdeco ignores them).
* **COLMAP** sparse model, text or binary: :mod:`harness.io.colmap`.
* **NeRF ``transforms.json``** (Blender synthetic, instant-ngp, nerfstudio): ``frames[i].transform_matrix``
  is camera-to-world in **OpenGL** axes (x right, y up, z backward); OpenCV axes are obtained by negating
  the y and z camera axes: ``c2w_cv = c2w_gl · diag(1, −1, −1, 1)``. Intrinsics per frame override the
  top level: ``fl_x, fl_y, cx, cy, w, h`` (pixels; ``fl_y`` defaults to ``fl_x``, ``cx, cy`` to the
  image centre), or ``camera_angle_x`` [``camera_angle_y``] with ``fl = ½ w / tan(½ angle)``. When
  ``w, h`` are absent (Blender sets) the size is read from the frame's image file header.
* **PLY header comments**: MPEG's gsTools ``comment camera_position ...`` lines before ``format``
  (:mod:`harness.io.gscameras`: syntax, pose convention, image size). :func:`ply_camera_comments`
  makes them (``write_ply`` puts them before ``format`` wherever they are passed);
  :func:`read_ply_cameras` / :func:`embedded_cameras` read them. Files from earlier versions of
  this harness carry ``comment camera {JSON}`` lines (:meth:`Camera.to_dict`); those are still read.

Every reader validates: numbers stored as numbers (``"fx": "55.4"`` and ``"width": true`` are
errors), finite, sizes integral, positive and within the maximum render size
(:data:`harness.core.cameras.MAX_SIDE`), focal lengths within
:data:`harness.core.cameras.FOCAL_RANGE`, a proper rotation (orthonormal to 1e-3, then
re-orthonormalised by SVD). Files are read through :mod:`harness.io.safe` (regular files,
size-capped, bounded nesting). Anything else is an :class:`InputError`.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from harness.core.cameras import Camera, intrinsics_problem, is_real, size_problem
from harness.core.errors import InputError
from harness.io.colmap import find_colmap_model, read_colmap_model

GL_TO_CV = np.diag([1.0, -1.0, -1.0, 1.0])
PLY_CAMERA_TAG = "camera "  # the comment text after "comment "


# ------------------------------------------------------------------------------ helpers
def _numbers(value, shape, source, what: str, name: str) -> np.ndarray:
    """A nested list of real numbers of ``shape`` as float64 (strings, bools, ragged lists refused)."""
    def ok(v, dims):
        if not dims:
            return is_real(v)
        return isinstance(v, (list, tuple, np.ndarray)) and len(v) == dims[0] and all(ok(x, dims[1:]) for x in v)

    if not ok(value, shape):
        raise InputError(source, f"{what}: {name} must be {' x '.join(map(str, shape))} numbers")
    with np.errstate(over="ignore"):
        return np.asarray(value, np.float64)


def _proper_rotation(r, source, what: str) -> np.ndarray:
    r = _numbers(r, (3, 3), source, what, "rotation")
    if r.shape != (3, 3) or not np.all(np.isfinite(r)):
        raise InputError(source, f"{what}: rotation must be a finite 3x3 matrix")
    if np.abs(r.T @ r - np.eye(3)).max() > 1e-3 or np.linalg.det(r) < 0:
        raise InputError(source, f"{what}: rotation is not a proper orthonormal matrix")
    u, _, vt = np.linalg.svd(r)
    return u @ vt


def _camera_from_c2w(rot_c2w, center, fx, fy, cx, cy, width, height, name, source) -> Camera:
    """Build a Camera from a camera-to-world rotation and centre (both OpenCV axes)."""
    what = f"camera {str(name)[:80]!r}"
    why = size_problem(width, height) or intrinsics_problem(fx, fy, cx, cy)
    if why:
        raise InputError(source, f"{what}: {why}")
    vals = [float(v) for v in (fx, fy, cx, cy)]
    w, h = int(width), int(height)
    center = _numbers(list(np.ravel(center)) if isinstance(center, np.ndarray) else center, (3,), source, what,
                      "position")
    if not np.all(np.isfinite(center)) or np.abs(center).max() > 1e12:
        raise InputError(source, f"{what}: position must be finite")
    r_w2c = _proper_rotation(rot_c2w, source, what).T
    m = np.eye(4)
    m[:3, :3] = r_w2c
    m[:3, 3] = -r_w2c @ center
    return Camera(m, *vals, w, h, str(name))


def _read_json(path: Path):
    from harness.io.safe import read_json

    return read_json(path, "json", "camera file")


# ------------------------------------------------------------------------------ 3DGS cameras.json
def read_3dgs_cameras(path: str | Path) -> list[Camera]:
    """Cameras of a graphdeco ``cameras.json`` in file order."""
    path = Path(path)
    data = _read_json(path)
    if not isinstance(data, list) or not data:
        raise InputError(path, "expected a non-empty JSON list of cameras (3DGS cameras.json)")
    out = []
    for i, d in enumerate(data):
        if not isinstance(d, dict):
            raise InputError(path, f"entry {i} is not an object")
        missing = [k for k in ("width", "height", "position", "rotation", "fx", "fy") if k not in d]
        if missing:
            raise InputError(path, f"entry {i} lacks {', '.join(missing)}")
        name = d.get("img_name", d.get("id", i))
        w, h = d["width"], d["height"]
        cx, cy = d.get("cx", _half(w)), d.get("cy", _half(h))
        out.append(_camera_from_c2w(d["rotation"], d["position"], d["fx"], d["fy"], cx, cy, w, h, name, path))
    return out


def _half(v):
    return v / 2.0 if is_real(v) else v


def cameras_to_3dgs_json(cameras: list[Camera]) -> list[dict]:
    """The graphdeco ``cameras.json`` records of ``cameras`` (extra ``cx``/``cy`` when off-centre)."""
    out = []
    for i, cam in enumerate(cameras):
        rec = {
            "id": i,
            "img_name": cam.name or f"view_{i:04d}",
            "width": int(cam.width),
            "height": int(cam.height),
            "position": cam.center.tolist(),
            "rotation": cam.rotation.T.tolist(),
            "fx": float(cam.fx),
            "fy": float(cam.fy),
        }
        if not (math.isclose(cam.cx, cam.width / 2.0) and math.isclose(cam.cy, cam.height / 2.0)):
            rec["cx"], rec["cy"] = float(cam.cx), float(cam.cy)
        out.append(rec)
    return out


def write_3dgs_cameras(cameras: list[Camera], path: str | Path) -> None:
    """Write a graphdeco ``cameras.json`` atomically (temp file + rename)."""
    from harness.io.files import atomic_write_text

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(path, json.dumps(cameras_to_3dgs_json(cameras), indent=1, allow_nan=False))


# ------------------------------------------------------------------------------ NeRF transforms.json
def _image_size(base: Path, file_path: str) -> tuple[int, int] | None:
    """(w, h) from the header of a frame's image (bounded read: a FIFO, a decompression bomb or a
    header beyond the maximum render size is an InputError naming the image); None when absent."""
    from harness.io.safe import image_size

    p = base / file_path
    for cand in (p, *(p.with_name(p.name + ext) for ext in (".png", ".jpg", ".jpeg", ".exr"))):
        if cand.exists():
            return image_size(cand, "frame image")
    return None


def read_transforms_json(path: str | Path) -> list[Camera]:
    """Cameras of a NeRF ``transforms.json`` in frame order (OpenGL -> OpenCV axes)."""
    path = Path(path)
    data = _read_json(path)
    if not isinstance(data, dict) or not isinstance(data.get("frames"), list) or not data["frames"]:
        raise InputError(path, "expected an object with a non-empty 'frames' list (NeRF transforms.json)")
    out = []
    for i, frame in enumerate(data["frames"]):
        if not isinstance(frame, dict) or "transform_matrix" not in frame:
            raise InputError(path, f"frame {i} lacks transform_matrix")
        def get(key, default=None, frame=frame):
            return frame.get(key, data.get(key, default))

        name = str(frame.get("file_path", f"frame_{i:04d}"))
        w, h = get("w"), get("h")
        if w is None or h is None:
            size = _image_size(path.parent, name)
            if size is None:
                raise InputError(path, f"frame {i}: no w/h and its image {name!r} cannot be read for its size")
            w, h = size
        why = size_problem(w, h)
        if why:
            raise InputError(path, f"frame {i}: {why}")
        w, h = int(w), int(h)

        def angle(key):
            a = get(key)
            if not is_real(a) or not 0.0 < float(a) < math.pi:
                raise InputError(path, f"frame {i}: {key} must be an angle in (0, pi) radians, got {a!r}")
            return float(a)

        if get("fl_x") is not None:
            fx = get("fl_x")
            fy = get("fl_y", fx)
        elif get("camera_angle_x") is not None:
            fx = 0.5 * w / math.tan(0.5 * angle("camera_angle_x"))
            fy = fx if get("camera_angle_y") is None else 0.5 * h / math.tan(0.5 * angle("camera_angle_y"))
        else:
            raise InputError(path, f"frame {i}: no focal length (fl_x or camera_angle_x)")
        cx, cy = get("cx", w / 2.0), get("cy", h / 2.0)
        raw = frame["transform_matrix"]
        rows = len(raw) if isinstance(raw, list) else 0
        m = _numbers(raw, (rows if rows in (3, 4) else 4, 4), path, f"frame {i}", "transform_matrix")
        if m.shape == (3, 4):
            m = np.vstack([m, [0.0, 0.0, 0.0, 1.0]])
        c2w = m @ GL_TO_CV
        out.append(_camera_from_c2w(c2w[:3, :3], c2w[:3, 3], fx, fy, cx, cy, w, h, name, path))
    return out


# ------------------------------------------------------------------------------ PLY header
def ply_camera_comments(cameras: list[Camera]) -> list[str]:
    """gsTools ``camera_position`` comment texts of ``cameras`` (:func:`harness.io.gscameras.camera_lines`)
    for :func:`harness.io.ply.write_ply`, which writes them before the ``format`` line."""
    from harness.io.gscameras import camera_lines

    return camera_lines(cameras)


def cameras_from_comments(comments, source, width: int | None = None, height: int | None = None) -> list[Camera]:
    """Cameras in header comment texts: gsTools ``camera_position`` lines (image size ``width ×
    height``, see :mod:`harness.io.gscameras`), else legacy ``camera {JSON}`` lines; others ignored."""
    from harness.io.gscameras import cameras_from_lines

    comments = list(comments)
    gs = cameras_from_lines(comments, source, width, height)
    if gs:
        return gs
    out = []
    for text in comments:
        if not text.startswith(PLY_CAMERA_TAG):
            continue
        try:
            d = json.loads(text[len(PLY_CAMERA_TAG):])
            if not isinstance(d, dict):
                raise ValueError("expected a JSON object")
            m = _numbers(d["world_to_cam"], (4, 4), source, "camera comment", "world_to_cam")
            if m.shape != (4, 4) or np.abs(m[3] - [0, 0, 0, 1]).max() > 1e-9:
                raise ValueError("world_to_cam must be a 4x4 rigid transform")
            name = d.get("name") or f"view_{len(out):04d}"
            r = _proper_rotation(m[:3, :3], source, f"camera {name!r}")
            out.append(_camera_from_c2w(r.T, -r.T @ m[:3, 3], d["fx"], d["fy"], d["cx"], d["cy"],
                                        d["width"], d["height"], name, source))
        except (json.JSONDecodeError, KeyError, TypeError, ValueError, RecursionError) as err:
            raise InputError(source, f"malformed camera comment ({err}): {text[:80]!r}") from None
    return out


def read_ply_cameras(path: str | Path, width: int | None = None, height: int | None = None) -> list[Camera]:
    """Cameras in a PLY header's comments (may be empty); the body is never read."""
    from harness.io.ply import read_ply_header

    header = read_ply_header(path)
    return cameras_from_comments(header.preamble + header.comments, Path(path), width, height)


def embedded_cameras(scene, width: int | None = None, height: int | None = None) -> list[Camera]:
    """Cameras a loaded scene's file carried in its header (``scene.meta``; may be empty)."""
    return cameras_from_comments(scene.meta.all_comments, scene.meta.source or "scene", width, height)


# ------------------------------------------------------------------------------ dispatch
def load_cameras(path: str | Path) -> list[Camera]:
    """Read cameras from any supported file or folder.

    A folder: its ``cameras.json``, ``transforms.json`` or COLMAP model (``.``, ``sparse/0``,
    ``sparse``), first found in that order. A ``.json`` file: a list is 3DGS, an object with
    ``frames`` is NeRF. A ``.ply``: header camera comments. ``cameras.{txt,bin}`` /
    ``images.{txt,bin}``: their COLMAP model folder. No cameras found -> :class:`InputError`.
    """
    path = Path(path)
    if not path.exists():
        raise InputError(path, "no such file or folder")
    if not path.is_dir():
        from harness.io.safe import check_regular

        check_regular(path, "json", "camera file")
    if path.is_dir():
        for fname in ("cameras.json", "transforms.json"):
            if (path / fname).is_file():
                return load_cameras(path / fname)
        if find_colmap_model(path) is not None:
            return read_colmap_model(path)
        raise InputError(path, "folder has no cameras.json, transforms.json or COLMAP sparse model")
    suffix = path.suffix.lower()
    if suffix == ".json":
        data = _read_json(path)
        if isinstance(data, list):
            return read_3dgs_cameras(path)
        if isinstance(data, dict) and "frames" in data:
            return read_transforms_json(path)
        raise InputError(path, "JSON is neither a 3DGS cameras list nor a NeRF transforms object")
    if suffix == ".ply":
        cams = read_ply_cameras(path)
        if not cams:
            raise InputError(path, "PLY header has no 'comment camera_position ...' lines")
        return cams
    if path.name in ("cameras.txt", "images.txt", "cameras.bin", "images.bin"):
        return read_colmap_model(path.parent)
    raise InputError(path, "unknown camera file type (expected .json, .ply or a COLMAP model)")
