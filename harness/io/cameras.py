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

Every reader validates: finite numbers, positive sizes and focal lengths, a proper rotation
(orthonormal to 1e-3, then re-orthonormalised by SVD). Anything else is an :class:`InputError`.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from harness.core.cameras import Camera
from harness.core.errors import InputError
from harness.io.colmap import find_colmap_model, read_colmap_model

GL_TO_CV = np.diag([1.0, -1.0, -1.0, 1.0])
PLY_CAMERA_TAG = "camera "  # the comment text after "comment "


# ------------------------------------------------------------------------------ helpers
def _proper_rotation(r, source, what: str) -> np.ndarray:
    r = np.asarray(r, np.float64)
    if r.shape != (3, 3) or not np.all(np.isfinite(r)):
        raise InputError(source, f"{what}: rotation must be a finite 3x3 matrix")
    if np.abs(r.T @ r - np.eye(3)).max() > 1e-3 or np.linalg.det(r) < 0:
        raise InputError(source, f"{what}: rotation is not a proper orthonormal matrix")
    u, _, vt = np.linalg.svd(r)
    return u @ vt


def _camera_from_c2w(rot_c2w, center, fx, fy, cx, cy, width, height, name, source) -> Camera:
    """Build a Camera from a camera-to-world rotation and centre (both OpenCV axes)."""
    what = f"camera {name!r}"
    try:
        vals = [float(v) for v in (fx, fy, cx, cy)]
        w, h = int(width), int(height)
        center = np.asarray(center, np.float64).reshape(3)
    except (TypeError, ValueError):
        raise InputError(source, f"{what}: non-numeric intrinsics, size or position") from None
    if w != width or h != height or w < 1 or h < 1:
        raise InputError(source, f"{what}: width/height must be positive integers")
    if not np.all(np.isfinite(vals)) or vals[0] <= 0 or vals[1] <= 0 or not np.all(np.isfinite(center)):
        raise InputError(source, f"{what}: focal lengths must be positive and all values finite")
    r_w2c = _proper_rotation(rot_c2w, source, what).T
    m = np.eye(4)
    m[:3, :3] = r_w2c
    m[:3, 3] = -r_w2c @ center
    return Camera(m, *vals, w, h, str(name))


def _read_json(path: Path):
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
        raise InputError(path, f"not a readable JSON file: {err}") from None


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
    return v / 2.0 if isinstance(v, (int, float)) else v


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
    atomic_write_text(path, json.dumps(cameras_to_3dgs_json(cameras), indent=1))


# ------------------------------------------------------------------------------ NeRF transforms.json
def _image_size(base: Path, file_path: str) -> tuple[int, int] | None:
    from PIL import Image  # header read only

    p = base / file_path
    for cand in (p, *(p.with_name(p.name + ext) for ext in (".png", ".jpg", ".jpeg", ".exr"))):
        if cand.is_file():
            try:
                with Image.open(cand) as im:
                    return im.size
            except OSError:
                return None
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
        try:
            w, h = float(w), float(h)
            if get("fl_x") is not None:
                fx = float(get("fl_x"))
                fy = float(get("fl_y", fx))
            elif get("camera_angle_x") is not None:
                fx = 0.5 * w / math.tan(0.5 * float(get("camera_angle_x")))
                ay = get("camera_angle_y")
                fy = fx if ay is None else 0.5 * h / math.tan(0.5 * float(ay))
            else:
                raise InputError(path, f"frame {i}: no focal length (fl_x or camera_angle_x)")
            cx, cy = float(get("cx", w / 2.0)), float(get("cy", h / 2.0))
            m = np.asarray(frame["transform_matrix"], np.float64)
        except (TypeError, ValueError):
            raise InputError(path, f"frame {i}: non-numeric intrinsics or transform_matrix") from None
        if m.shape == (3, 4):
            m = np.vstack([m, [0.0, 0.0, 0.0, 1.0]])
        if m.shape != (4, 4):
            raise InputError(path, f"frame {i}: transform_matrix must be 4x4 or 3x4")
        c2w = m @ GL_TO_CV
        out.append(_camera_from_c2w(c2w[:3, :3], c2w[:3, 3], fx, fy, cx, cy, int(w), int(h), name, path))
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
            m = np.asarray(d["world_to_cam"], np.float64)
            if m.shape != (4, 4) or np.abs(m[3] - [0, 0, 0, 1]).max() > 1e-9:
                raise ValueError("world_to_cam must be a 4x4 rigid transform")
            name = d.get("name") or f"view_{len(out):04d}"
            r = _proper_rotation(m[:3, :3], source, f"camera {name!r}")
            out.append(_camera_from_c2w(r.T, -r.T @ m[:3, 3], d["fx"], d["fy"], d["cx"], d["cy"],
                                        d["width"], d["height"], name, source))
        except (json.JSONDecodeError, KeyError, TypeError, ValueError) as err:
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
