"""The N viewpoints mpeg-gsc-metrics places itself when a scene has no cameras (its ``-n N``).

Source (ISO/IEC, BSD), read, no code copied: github.com/little-little-point-cloud-group/gscem @
c4a0c1cae569…, ``submodules/mpeg-gsc-metrics/source/``: ``util/viewpoints.hpp``
(``Viewpoints::create``), ``main.cpp`` (``viewpoints.create( params.numPoints_, center )`` with the
source's bounding-box centre; ``-n/--numPoints`` default 16, ``--width/--height`` default 1024×768),
``util/camera.hpp`` (``Camera::setLookAt``, ``viewMat``), ``rasterizerSoftware.cpp`` (fov from focal.y).

``Viewpoints::create(N, c, radius = 5, focal = 2000)`` — a Fibonacci sphere of fixed radius 5 (scene
units, whatever the scene's size) around ``c = (min + max)/2`` of the *source's* splat centres::

    N = 1:  eye = c + (5, 0, 0),  up = (0, 1, 0)
    N > 1:  for i = 0 .. N−1:  z = 1 − 2i/(N − 1),  r = √(1 − z²),  φ = i·π(3 − √5)
            eye = c + 5·(r cos φ, r sin φ, z)
            right = normalize(y × c),  up = c × right       (y = (0, 1, 0))

Every viewpoint looks at ``c`` with focal 2000 px on both axes. Note the tool's quirk: ``right`` and
``up`` are built from the centre *point* ``c`` (the variable is named ``view``), not from the view
direction, so ``up`` is the y axis with its component along ``c`` removed, the same for every view.
When ``c`` lies on the y axis (x = z = 0, e.g. a scene centred at the origin) ``y × c`` vanishes and
the tool normalises a zero vector (NaN cameras, nothing rendered); we refuse such a scene.

``Camera::setLookAt(eye, c, up)`` then builds ``e_z = normalize(eye − c)``, ``e_x = normalize(up ×
e_z)``, ``e_y = e_z × e_x`` and renders with ``glm::lookAt`` (OpenGL: looking along −e_z, e_y up) and
``glm::perspective(2·atan(H / (2·2000)), W/H)``, i.e. ``fx = fy = 2000`` px, principal point at the
centre. In OpenCV axes (:class:`harness.core.cameras.Camera`) the rows of ``world_to_cam`` are
``e_x, −e_y, −e_z``. The tool computes in float32 and round-trips the rotation through a quaternion.
We take ``z``, ``r`` and ``φ`` rounded to float32 as it does (``φ`` reaches 36 rad for N = 16, where
a float32 step is 4e-6 rad, i.e. 2e-5 units at radius 5) and compute the rest in float64, so poses
agree with the tool's to float32 rounding (~1e-7 relative).
"""

from __future__ import annotations

import math

import numpy as np

from harness.core.cameras import Camera

#: mpeg-gsc-metrics defaults: ``-n`` 16, ``Viewpoints::create`` radius 5 and focal 2000, 1024×768
DEFAULT_VIEWS = 16
RADIUS = 5.0
FOCAL = 2000.0
TOOL_SIZE = (1024, 768)
#: ``glm::pi<float>() * ( 3.0f - glm::sqrt( 5.0f ) )``, float32
_GOLDEN_ANGLE = np.float32(math.pi) * (np.float32(3.0) - np.sqrt(np.float32(5.0)))


class ViewpointError(ValueError):
    """The tool's placement is undefined for this scene (its centre lies on the y axis)."""


def box_centre(means: np.ndarray) -> np.ndarray:
    """``(min + max) · 0.5`` of the splat centres, in float32 as ``Pointcloud::getBoundingBox``."""
    m = np.asarray(means, np.float32)
    return ((m.max(axis=0) + m.min(axis=0)) * np.float32(0.5)).astype(np.float64)


def _unit(v: np.ndarray) -> np.ndarray | None:
    """``v / |v|``, or None for a zero vector (which ``glm::normalize`` turns into NaN)."""
    n = float(np.linalg.norm(v))
    return v / n if n > 0 and math.isfinite(n) else None


def tool_poses(n: int, centre) -> list[tuple[np.ndarray, np.ndarray]]:
    """(eye, up) of each viewpoint of ``Viewpoints::create(n, centre)`` (module docstring)."""
    if n < 1:
        raise ValueError(f"the number of viewpoints must be at least 1, got {n}")
    c = np.asarray(centre, np.float64)
    y = np.array([0.0, 1.0, 0.0])
    if n == 1:
        return [(c + np.array([RADIUS, 0.0, 0.0]), y)]
    right = _unit(np.cross(y, c))
    if right is None:
        raise ViewpointError(f"the bounding-box centre ({c[0]:g}, {c[1]:g}, {c[2]:g}) lies on the y axis, where "
                             "mpeg-gsc-metrics' up vector normalize(y × centre) is undefined (the tool renders NaN "
                             "cameras there)")
    up = np.cross(c, right)
    f32 = np.float32
    out = []
    for i in range(n):  # z, r, φ in float32 as the tool computes them (φ reaches 2.4·(N − 1) rad)
        z = f32(1.0) - (f32(2.0) * f32(i)) / f32(n - 1)
        r = float(np.sqrt(f32(1.0) - z * z))
        phi = float(f32(i) * _GOLDEN_ANGLE)
        out.append((c + RADIUS * np.array([r * math.cos(phi), r * math.sin(phi), float(z)]), up))
    return out


def look_at(eye, centre, up, width: int, height: int, focal: float = FOCAL, name: str = "") -> Camera:
    """``Camera::setLookAt`` + ``glm::lookAt`` as an OpenCV-axes :class:`Camera` (fx = fy = focal)."""
    eye, centre = np.asarray(eye, np.float64), np.asarray(centre, np.float64)
    e_z = _unit(eye - centre)
    e_x = None if e_z is None else _unit(np.cross(up, e_z))
    if e_x is None:
        raise ViewpointError(f"viewpoint {name or ''} looks along its up vector; the tool's camera is undefined")
    e_y = np.cross(e_z, e_x)
    m = np.eye(4)
    m[:3, :3] = np.stack([e_x, -e_y, -e_z])
    m[:3, 3] = -m[:3, :3] @ eye
    return Camera(m, focal, focal, width / 2.0, height / 2.0, int(width), int(height), name)


def tool_viewpoints(means: np.ndarray, n: int = DEFAULT_VIEWS, width: int | None = None,
                    height: int | None = None) -> tuple[list[Camera], np.ndarray]:
    """(cameras, centre): the ``n`` viewpoints mpeg-gsc-metrics renders for a source scene with
    splat centres ``means``, at ``width × height`` (default the tool's 1024×768)."""
    w, h = int(width or TOOL_SIZE[0]), int(height or TOOL_SIZE[1])
    c = box_centre(means)
    digits = max(2, len(str(n - 1)))
    cams = [
        look_at(eye, c, up, w, h, FOCAL, f"viewpoint_{i:0{digits}d}") for i, (eye, up) in enumerate(tool_poses(n, c))
    ]
    return cams, c
