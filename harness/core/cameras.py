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
        z /= np.linalg.norm(z)
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
        """The same view at a new resolution whose longest side is ``longest_side`` pixels."""
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
