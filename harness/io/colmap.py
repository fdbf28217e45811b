"""COLMAP sparse models (text and binary) -> ``list[Camera]``.

Only ``cameras`` and ``images`` are read (``points3D`` is not needed for views). Conventions:

* ``images``: ``qvec = (qw, qx, qy, qz)`` and ``tvec`` give the **world-to-camera** transform in
  OpenCV axes, ``x_cam = R(q) x_world + t`` — exactly :attr:`Camera.world_to_cam`.
* ``cameras``: the principal point ``(cx, cy)`` is in COLMAP's pixel frame, where the top-left
  pixel's centre is (0.5, 0.5): the same frame as :class:`Camera`, so it is copied unchanged.
* Distortion parameters (OPENCV, RADIAL, fisheye models …) are dropped: the renderer is a pinhole,
  as in 3DGS, which trains on undistorted images. Models are mapped to ``(fx, fy, cx, cy)``.
* Cameras are returned sorted by image name (the 3DGS loader's order), so a held-out split such as
  "every 8th view" means the same thing as in 3DGS.

Binary layout (little endian): ``cameras.bin`` = u64 count, then per camera i32 id, i32 model id,
u64 width, u64 height, f64 params[n(model)]; ``images.bin`` = u64 count, then per image u32 id,
f64 qvec[4], f64 tvec[3], u32 camera id, NUL-terminated name, u64 n_points2D, n × (f64 x, f64 y,
i64 point3D id).
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

from harness.core.cameras import Camera, intrinsics_problem, size_problem
from harness.core.errors import InputError


def _f_cxcy(p):  # params f, cx, cy, ...
    return p[0], p[0], p[1], p[2]


def _fx_fy_cxcy(p):  # params fx, fy, cx, cy, ...
    return p[0], p[1], p[2], p[3]


#: model id -> (name, number of params, function params -> (fx, fy, cx, cy))
CAMERA_MODELS = {
    0: ("SIMPLE_PINHOLE", 3, _f_cxcy),
    1: ("PINHOLE", 4, _fx_fy_cxcy),
    2: ("SIMPLE_RADIAL", 4, _f_cxcy),
    3: ("RADIAL", 5, _f_cxcy),
    4: ("OPENCV", 8, _fx_fy_cxcy),
    5: ("OPENCV_FISHEYE", 8, _fx_fy_cxcy),
    6: ("FULL_OPENCV", 12, _fx_fy_cxcy),
    7: ("FOV", 5, _fx_fy_cxcy),
    8: ("SIMPLE_RADIAL_FISHEYE", 4, _f_cxcy),
    9: ("RADIAL_FISHEYE", 5, _f_cxcy),
    10: ("THIN_PRISM_FISHEYE", 12, _fx_fy_cxcy),
}
MODEL_IDS = {name: mid for mid, (name, _, _) in CAMERA_MODELS.items()}


def qvec_to_rotmat(q) -> np.ndarray:
    """Rotation matrix of the (normalised) quaternion (w, x, y, z)."""
    w, x, y, z = np.asarray(q, np.float64) / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def _intrinsics(model_id: int, params, source) -> tuple[float, float, float, float]:
    if model_id not in CAMERA_MODELS:
        raise InputError(source, f"unknown COLMAP camera model id {model_id}")
    name, n, fn = CAMERA_MODELS[model_id]
    if len(params) != n:
        raise InputError(source, f"{name} camera needs {n} parameters, got {len(params)}")
    return tuple(float(v) for v in fn(params))


def _make_camera(qvec, tvec, intr, width, height, name, source) -> Camera:
    q = np.asarray(qvec, np.float64)
    if not np.all(np.isfinite(q)) or not np.all(np.isfinite(tvec)) or np.linalg.norm(q) < 1e-12:
        raise InputError(source, f"image {name!r} has a non-finite or zero quaternion/translation")
    m = np.eye(4)
    m[:3, :3] = qvec_to_rotmat(q)
    m[:3, 3] = np.asarray(tvec, np.float64)
    fx, fy, cx, cy = intr
    why = size_problem(width, height) or intrinsics_problem(fx, fy, cx, cy)
    if why:
        raise InputError(source, f"image {name!r}: {why}")
    return Camera(m, fx, fy, cx, cy, int(width), int(height), name)


# ------------------------------------------------------------------------------ text
def _data_lines(path: Path) -> list[str]:
    from harness.io.safe import read_text

    text = read_text(path, "camera_model", "COLMAP file")
    return [ln for ln in text.splitlines() if not ln.lstrip().startswith("#")]


def _read_cameras_txt(path: Path) -> dict[int, tuple]:
    cams = {}
    for ln in _data_lines(path):
        tok = ln.split()
        if not tok:
            continue
        try:
            cid, model, w, h = int(tok[0]), tok[1], int(tok[2]), int(tok[3])
            params = [float(v) for v in tok[4:]]
        except (ValueError, IndexError):
            raise InputError(path, f"malformed camera line: {ln.strip()!r}") from None
        if model not in MODEL_IDS:
            raise InputError(path, f"unknown COLMAP camera model {model!r}")
        cams[cid] = (_intrinsics(MODEL_IDS[model], params, path), w, h)
    return cams


def _read_images_txt(path: Path) -> list[tuple]:
    """(qvec, tvec, camera_id, name) per image. Each image is a header line followed by one
    POINTS2D line (possibly empty), so lines are consumed in pairs after dropping comments."""
    lines = _data_lines(path)
    out, i = [], 0
    while i < len(lines):
        tok = lines[i].split()
        if not tok:  # blank line between records / at end of file
            i += 1
            continue
        try:
            q = [float(v) for v in tok[1:5]]
            t = [float(v) for v in tok[5:8]]
            cid = int(tok[8])
            name = " ".join(tok[9:])
        except (ValueError, IndexError):
            raise InputError(path, f"malformed image line: {lines[i].strip()!r}") from None
        if not name:
            raise InputError(path, f"image line without a name: {lines[i].strip()!r}")
        out.append((q, t, cid, name))
        i += 2  # skip the POINTS2D line
    return out


# ------------------------------------------------------------------------------ binary
class _Reader:
    def __init__(self, path: Path):
        from harness.io.safe import read_bytes

        self.path = path
        self.buf = read_bytes(path, "camera_model", "COLMAP file")
        self.pos = 0

    def take(self, fmt: str):
        size = struct.calcsize(fmt)
        if self.pos + size > len(self.buf):
            raise InputError(self.path, f"truncated at byte {self.pos} (needs {size} more)")
        vals = struct.unpack_from(fmt, self.buf, self.pos)
        self.pos += size
        return vals

    def cstring(self) -> str:
        end = self.buf.find(b"\0", self.pos)
        if end < 0:
            raise InputError(self.path, "truncated image name")
        s = self.buf[self.pos:end].decode("utf-8", "replace")
        self.pos = end + 1
        return s


def _read_cameras_bin(path: Path) -> dict[int, tuple]:
    r, cams = _Reader(path), {}
    (count,) = r.take("<Q")
    for _ in range(count):
        cid, model, w, h = r.take("<iiQQ")
        if model not in CAMERA_MODELS:
            raise InputError(path, f"unknown COLMAP camera model id {model}")
        params = r.take(f"<{CAMERA_MODELS[model][1]}d")
        cams[cid] = (_intrinsics(model, params, path), w, h)
    if r.pos != len(r.buf):
        raise InputError(path, f"{len(r.buf) - r.pos} unexpected trailing bytes")
    return cams


def _read_images_bin(path: Path) -> list[tuple]:
    r, out = _Reader(path), []
    (count,) = r.take("<Q")
    for _ in range(count):
        vals = r.take("<I7dI")
        name = r.cstring()
        (npts,) = r.take("<Q")
        if r.pos + 24 * npts > len(r.buf):
            raise InputError(path, f"truncated 2D points of image {name!r}")
        r.pos += 24 * npts
        out.append((vals[1:5], vals[5:8], vals[8], name))
    if r.pos != len(r.buf):
        raise InputError(path, f"{len(r.buf) - r.pos} unexpected trailing bytes")
    return out


# ------------------------------------------------------------------------------ public
def find_colmap_model(path: str | Path) -> Path | None:
    """The folder holding ``cameras.{bin,txt}`` + ``images.{bin,txt}``: ``path`` itself or
    ``path/sparse/0`` or ``path/sparse``; None when there is none."""
    path = Path(path)
    for d in (path, path / "sparse" / "0", path / "sparse"):
        for ext in ("bin", "txt"):
            if (d / f"cameras.{ext}").is_file() and (d / f"images.{ext}").is_file():
                return d
    return None


def read_colmap_model(path: str | Path) -> list[Camera]:
    """Cameras of a COLMAP sparse model folder (binary preferred when both exist)."""
    model = find_colmap_model(path)
    if model is None:
        raise InputError(path, "no COLMAP model (cameras.bin/txt and images.bin/txt) found")
    binary = (model / "cameras.bin").is_file() and (model / "images.bin").is_file()
    if binary:
        cams_path, imgs_path = model / "cameras.bin", model / "images.bin"
        cams, imgs = _read_cameras_bin(cams_path), _read_images_bin(imgs_path)
    else:
        cams_path, imgs_path = model / "cameras.txt", model / "images.txt"
        cams, imgs = _read_cameras_txt(cams_path), _read_images_txt(imgs_path)
    out = []
    for q, t, cid, name in imgs:
        if cid not in cams:
            raise InputError(imgs_path, f"image {name!r} refers to missing camera id {cid}")
        intr, w, h = cams[cid]
        why = size_problem(w, h) or intrinsics_problem(*intr)
        if why:
            raise InputError(cams_path, f"camera {cid}: {why}")
        out.append(_make_camera(q, t, intr, w, h, name, imgs_path))
    if not out:
        raise InputError(imgs_path, "the model has no registered images")
    return sorted(out, key=lambda c: c.name)
