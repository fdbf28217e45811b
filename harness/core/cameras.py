"""`Camera`: a pinhole camera in OpenCV axes (x right, y down, z forward).

``world_to_cam`` is the 4×4 matrix taking homogeneous world points to camera coordinates;
pixel ``(u, v) = (fx·x/z + cx, fy·y/z + cy)`` with pixel centres at integer + 0.5 convention
of the 3DGS rasterizer (pixel index i covers [i, i+1)). Readers for camera files live in
:mod:`harness.io.cameras`; synthetic rigs in :mod:`harness.views.rigs`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from harness.core.errors import InputError

#: the largest image any camera may ask for (camera files, rigs, ``--longest-side``, configs): 8192
#: pixels per side and 8192² = 64 Mi pixels in all — a float32 RGB render of that size is 768 MiB
MAX_SIDE = 8192
MAX_PIXELS = MAX_SIDE * MAX_SIDE
#: focal lengths (pixels) outside this range are refused: they overflow the projection maths
FOCAL_RANGE = (1e-3, 1e9)
#: largest absolute coordinate of a camera centre / principal point
COORD_MAX = 1e12


def is_real(v) -> bool:
    """A real number as a file would hold it: int or float (numpy scalars too), never bool or str."""
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_))


def is_whole(v) -> bool:
    """An integer, or a float with an integral finite value (some writers store 800.0)."""
    if isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_)):
        return True
    return isinstance(v, (float, np.floating)) and math.isfinite(v) and float(v).is_integer()


def size_problem(width, height) -> str | None:
    """Why (width, height) is not a renderable image size, or None."""
    if not (is_whole(width) and is_whole(height)):
        return f"width/height must be positive integers, got {width!r} x {height!r}"
    w, h = int(width), int(height)
    if w < 1 or h < 1:
        return f"width/height must be positive integers, got {w} x {h}"
    if w > MAX_SIDE or h > MAX_SIDE or w * h > MAX_PIXELS:
        return f"{w} x {h} pixels is larger than the maximum render size ({MAX_SIDE} per side)"
    return None


def intrinsics_problem(fx, fy, cx, cy) -> str | None:
    """Why focal lengths / principal point are unusable, or None."""
    if not all(is_real(v) for v in (fx, fy, cx, cy)):
        return "fx, fy, cx, cy must be numbers"
    if not all(math.isfinite(float(v)) for v in (fx, fy, cx, cy)):
        return "fx, fy, cx, cy must be finite"
    lo, hi = FOCAL_RANGE
    if not (lo <= float(fx) <= hi and lo <= float(fy) <= hi):
        return f"focal lengths must be positive, in [{lo:g}, {hi:g}] pixels, got {float(fx):g}, {float(fy):g}"
    if abs(float(cx)) > COORD_MAX or abs(float(cy)) > COORD_MAX:
        return "principal point is out of range"
    return None


def pose_problem(world_to_cam: np.ndarray) -> str | None:
    """Why a 4×4 world-to-camera matrix is not a pose a renderer can use, or None: every entry
    finite, a rigid transform (proper rotation + translation), the camera centre within
    ±:data:`COORD_MAX`."""
    m = world_to_cam
    if not np.all(np.isfinite(m)):
        return "world_to_cam must be finite (it holds NaN or inf)"
    r = m[:3, :3]
    if np.abs(m[3] - (0.0, 0.0, 0.0, 1.0)).max() > 1e-9 or np.abs(r @ r.T - np.eye(3)).max() > 1e-3 \
            or np.linalg.det(r) < 0:
        return "world_to_cam is not a rigid transform (proper rotation + translation)"
    center = np.abs(r.T @ m[:3, 3]).max()
    if center > COORD_MAX:
        return f"the camera centre lies {center:.3g} from the origin, beyond the ±{COORD_MAX:g} cameras may take"
    return None


def camera_problem(cam: "Camera") -> str | None:
    """Why a Camera cannot be rendered (size, intrinsics, a non-rigid or non-finite pose), or None."""
    return size_problem(cam.width, cam.height) or intrinsics_problem(cam.fx, cam.fy, cam.cx, cam.cy) \
        or pose_problem(np.asarray(cam.world_to_cam, np.float64))


class CameraError(InputError, ValueError):
    """A camera no renderer can use — a NaN or non-rigid pose, a centre beyond :data:`COORD_MAX`,
    unusable intrinsics: refused when the :class:`Camera` is made, whatever made it (camera files,
    rigs fitted to a scene, the API), so a NaN camera never exists. A ValueError too, for callers
    that validate cameras rebuilt from stored dicts."""


class CameraSizeError(CameraError):
    """A camera asking for an image beyond :data:`MAX_SIDE` (or of no pixels): refused when the
    :class:`Camera` is made, so no source of sizes — camera files, PLY header camera lines, rigs,
    configs, ``--width/--height`` — can reach a renderer with one."""


@dataclass(frozen=True)
class Camera:
    world_to_cam: np.ndarray  # (4, 4) float64
    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int
    name: str = ""

    def __post_init__(self) -> None:
        m = np.asarray(self.world_to_cam, dtype=np.float64)
        if m.shape != (4, 4):
            raise ValueError(f"world_to_cam must be 4x4, got {m.shape}")
        object.__setattr__(self, "world_to_cam", m)
        where = f"camera {self.name!r}" if self.name else "camera"
        why = size_problem(self.width, self.height)  # where every size enters: no bypass
        if why:
            raise CameraSizeError(where, why)
        why = intrinsics_problem(self.fx, self.fy, self.cx, self.cy) or pose_problem(m)
        if why:
            raise CameraError(where, why)

    # ---------------------------------------------------------------- geometry
    @property
    def rotation(self) -> np.ndarray:
        """World-to-camera rotation R (3, 3)."""
        return self.world_to_cam[:3, :3]

    @property
    def translation(self) -> np.ndarray:
        """World-to-camera translation t (3,)."""
        return self.world_to_cam[:3, 3]

    @property
    def center(self) -> np.ndarray:
        """Camera centre in world coordinates, −Rᵀt."""
        return -self.rotation.T @ self.translation

    @property
    def forward(self) -> np.ndarray:
        """Viewing direction (+z of the camera) in world coordinates."""
        return self.rotation[2]

    @property
    def fov_x(self) -> float:
        return 2.0 * math.atan(self.width / (2.0 * self.fx))

    @property
    def fov_y(self) -> float:
        return 2.0 * math.atan(self.height / (2.0 * self.fy))

    # ---------------------------------------------------------------- constructors
    @classmethod
    def look_at(
        cls,
        eye,
        target,
        up=(0.0, -1.0, 0.0),
        *,
        fov_y_deg: float = 50.0,
        width: int = 1024,
        height: int = 768,
        name: str = "",
    ) -> "Camera":
        """A camera at ``eye`` looking at ``target``; ``up`` is the world direction that should
        point *up* in the image (OpenCV y points down, so image-down = −up)."""
        eye = np.asarray(eye, np.float64)
        z = np.asarray(target, np.float64) - eye
        length = np.linalg.norm(z)
        if not (np.isfinite(length) and length > 0):  # eye == target: no viewing direction
            raise CameraError(f"camera {name!r}" if name else "camera",
                              f"cannot look from {eye.tolist()} at {np.asarray(target).tolist()}: no direction")
        z /= length
        up = np.asarray(up, np.float64)
        x = np.cross(-up, z)  # image right = down × forward (OpenCV: x = y × z)
        if np.linalg.norm(x) < 1e-9:  # looking along up: pick any perpendicular
            x = np.cross(z, np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0]))
        x /= np.linalg.norm(x)
        y = np.cross(z, x)
        rot = np.stack([x, y, z])
        m = np.eye(4)
        m[:3, :3] = rot
        m[:3, 3] = -rot @ eye
        fy = height / (2.0 * math.tan(math.radians(fov_y_deg) / 2.0))
        return cls(m, fy, fy, width / 2.0, height / 2.0, int(width), int(height), name)

    def resized(self, longest_side: int) -> "Camera":
        """The same view at a new resolution whose longest side is ``longest_side`` pixels
        (at most :data:`MAX_SIDE`)."""
        if not 1 <= longest_side <= MAX_SIDE:
            raise ValueError(f"longest side {longest_side} is outside 1..{MAX_SIDE}")
        s = longest_side / max(self.width, self.height)
        return replace(
            self,
            fx=self.fx * s,
            fy=self.fy * s,
            cx=self.cx * s,
            cy=self.cy * s,
            width=max(1, int(round(self.width * s))),
            height=max(1, int(round(self.height * s))),
        )

    def to_dict(self) -> dict:
        return {
            "name": self.name,
            "world_to_cam": self.world_to_cam.tolist(),
            "fx": self.fx,
            "fy": self.fy,
            "cx": self.cx,
            "cy": self.cy,
            "width": self.width,
            "height": self.height,
        }

    @classmethod
    def from_dict(cls, d: dict) -> "Camera":
        return cls(
            np.asarray(d["world_to_cam"], np.float64),
            float(d["fx"]), float(d["fy"]), float(d["cx"]), float(d["cy"]),
            int(d["width"]), int(d["height"]), str(d.get("name", "")),
        )
