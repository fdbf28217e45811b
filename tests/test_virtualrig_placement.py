"""Where the virtual rig puts its cameras: the support plane a scene stands on (no camera below it),
the room positions chosen by what they see (none under the table), and the picture that shows it."""

from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from harness.core.scene import GaussianScene
from harness.io.scenes import write_scene
from methods.virtualrig import VirtualRigParams, rig_report, support_of, virtual_cameras
from methods.virtualrig.coverage import greedy, sees_subject, visibility
from methods.virtualrig.rig import cap_directions
from methods.virtualrig.shape import analyse
from methods.virtualrig.support import find_support

REPO = __import__("pathlib").Path(__file__).resolve().parent.parent


def _splats(points, normals, size, flat=True, opacity_logit=4.0):
    """Splats at ``points``: discs (short axis along ``normals``) when ``flat``, else balls."""
    n = len(points)
    quats = np.array([_quat_to(nrm) for nrm in normals])
    scales = np.full((n, 3), math.log(size))
    if flat:
        scales[:, 2] = math.log(size * 0.05)
    return dict(means=points, scales_log=scales, quats=quats, opacity_logit=np.full(n, opacity_logit),
                sh_dc=np.full((n, 3), 0.3), sh_rest=np.zeros((n, 0, 3)))


def _quat_to(normal):
    """(w, x, y, z) of a rotation taking +z to ``normal``."""
    r = Rotation.align_vectors([normal], [[0.0, 0.0, 1.0]])[0]
    x, y, z, w = r.as_quat()
    return [w, x, y, z]


def _scene(*parts) -> GaussianScene:
    keys = parts[0].keys()
    arrays = {k: np.concatenate([p[k] for p in parts]) for k in keys}
    return GaussianScene.from_arrays(**arrays)


def _disc(n, radius, centre, normal, rng):
    normal = np.asarray(normal, float) / np.linalg.norm(normal)
    e1 = np.cross(normal, [1.0, 0, 0] if abs(normal[0]) < 0.9 else [0, 1.0, 0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(normal, e1)
    r, a = radius * np.sqrt(rng.uniform(size=n)), rng.uniform(0, 2 * math.pi, n)
    pts = np.asarray(centre) + (r * np.cos(a))[:, None] * e1 + (r * np.sin(a))[:, None] * e2
    return _splats(pts, np.tile(normal, (n, 1)), 0.08)


def _ball(n, radius, centre, rng):
    p = rng.normal(size=(n, 3))
    p /= np.linalg.norm(p, axis=1, keepdims=True)
    return _splats(np.asarray(centre) + radius * p, p, 0.06)  # a shell of discs tangent to the sphere


UP = np.array([0.3, 0.2, 0.9]) / np.linalg.norm([0.3, 0.2, 0.9])  # no axis of the frame: found, not assumed


def _standing_object(seed=0):
    """A ball standing on a ground disc, up = :data:`UP`."""
    rng = np.random.default_rng(seed)
    return _scene(_disc(6000, 2.5, np.zeros(3), UP, rng), _ball(3000, 0.6, 0.65 * UP, rng))


# ------------------------------------------------------------------ the support plane
def test_support_of_a_standing_object_is_its_ground():
    scene = _standing_object()
    shape = analyse(scene)
    sup = find_support(scene, shape.center, shape.radius, shape.cell)
    assert sup.up is not None and sup.up @ UP > math.cos(math.radians(2.0))
    assert -shape.cell <= sup.height <= 2 * shape.cell  # the ground's top face, at 0 along up
    assert sup.one_sided > 0.95 and sup.coverage > 0.9
    assert "support plane" in sup.describe()
    assert sup.above(np.array([UP, -UP])).tolist() == [True, False]


@pytest.mark.parametrize("what", ["floating ball", "ball with a lid"])
def test_no_support_under_a_floating_object_or_a_lid(what):
    rng = np.random.default_rng(1)
    parts = [_ball(4000, 1.0, np.zeros(3), rng)]
    if what == "ball with a lid":  # a flat top: one-sided, but it covers little of the footprint
        parts.append(_disc(800, 0.3, 1.0 * UP, UP, rng))
    scene = _scene(*parts)
    shape = analyse(scene)
    sup = find_support(scene, shape.center, shape.radius, shape.cell)
    assert sup.up is None and "no support" in sup.describe()
    assert sup.above(np.zeros((3, 3))).all()


def test_outside_in_cameras_stay_above_the_ground():
    scene = _standing_object()
    p = VirtualRigParams(views=40, resolution=32)
    shape, cams = virtual_cameras(scene, p)
    sup = support_of(scene, shape, p)
    heights = np.array([c.center @ sup.up for c in cams])
    assert shape.kind == "object" and np.all(heights >= sup.height + shape.cell - 1e-9)
    assert heights.max() > 0.9 * np.linalg.norm(cams[0].center - shape.center)  # right above, too
    full = virtual_cameras(scene, VirtualRigParams(views=40, resolution=32, support="off"))[1]
    assert (np.array([c.center @ UP for c in full]) < 0).sum() >= 15  # the old full sphere: half below


def test_cap_directions_cover_the_cap_evenly():
    up = np.array([0.0, 0.0, 1.0])
    d = cap_directions(400, up, -0.2, 0.3)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0)
    assert d[:, 2].min() >= -0.2 and d[:, 2].max() <= 1.0
    # equal-area: the share of directions above z = 0.4 is the cap's area share (1 − 0.4) / (1 + 0.2)
    assert (d[:, 2] > 0.4).mean() == pytest.approx(0.5, abs=0.01)


# ------------------------------------------------------------------ room positions by coverage
def _room_with_table(seed=0):
    """Six walls of the cube [-4, 4]³ (z up), a table top at z = −1 (3 × 3), a subject a cell above it
    (at the 32³ grid a subject sharing cells with its table top is seen through it: the docstring of
    methods/virtualrig/coverage.py)."""
    rng = np.random.default_rng(seed)
    parts = []
    for axis in range(3):
        for side in (-4.0, 4.0):
            pts = rng.uniform(-4, 4, size=(2500, 3))
            pts[:, axis] = side
            nrm = np.zeros((2500, 3))
            nrm[:, axis] = 1.0
            parts.append(_splats(pts, nrm, 0.25))
    top = rng.uniform(-1.5, 1.5, size=(3000, 3))
    top[:, 2] = -1.0
    parts.append(_splats(top, np.tile([0, 0, 1.0], (3000, 1)), 0.12))
    parts.append(_ball(3000, 0.35, [0.0, 0.0, -0.3], rng))
    return _scene(*parts)


def test_room_cameras_see_the_subject_and_none_stands_under_the_table():
    scene = _room_with_table()
    shape, cams = virtual_cameras(scene, VirtualRigParams(views=24, resolution=32, positions="coverage"))
    assert shape.kind == "room" and len(cams) == 24
    eyes = np.array([c.center for c in cams])
    under = (np.abs(eyes[:, 0]) < 1.5) & (np.abs(eyes[:, 1]) < 1.5) & (eyes[:, 2] < -1.0)
    assert not under.any()
    assert np.all(np.abs(eyes) < 4.0)
    for c in cams:
        to_peak = (shape.peak - c.center) / np.linalg.norm(shape.peak - c.center)
        assert c.forward @ to_peak == pytest.approx(1.0)
    # the rule that forbids it: from under the table top the subject is out of sight, from above not
    grid = lambda p: (p - shape.origin) / shape.cell
    seen = sees_subject(shape.occupied, shape.subject, grid(np.array([[0.0, 0.0, -2.5], [0.0, 0.0, 1.5]])),
                        grid(shape.peak))
    assert seen.tolist() == [False, True]
    assert not shape.subject[tuple(((np.array([1.2, 1.2, -1.0]) - shape.origin) // shape.cell).astype(int))]


def test_visibility_and_greedy_by_hand():
    occ = np.zeros((9, 3, 3), bool)
    occ[4, 1, 1] = occ[8, 1, 1] = True  # a blocker in the middle, a target at the end
    starts = np.array([[0.5, 1.5, 1.5], [6.5, 1.5, 1.5]])
    fwd = np.array([[1.0, 0, 0], [1.0, 0, 0]])
    seen = visibility(occ, starts, fwd, 60.0)  # columns: cell (4,1,1), cell (8,1,1)
    assert seen.tolist() == [[True, False], [False, True]]  # behind the start: outside its cone
    mass = np.array([1.0, 3.0])
    cand = np.array([[True, False], [False, True], [True, True]])
    assert greedy(cand, mass, 3).tolist() == [2, 1, 0]  # 4; then 1.5 vs 0.5; then 0.5


# ------------------------------------------------------------------ the picture
def test_rig_report_and_diagnose_draw_the_rig(tmp_path):
    scene = _standing_object()
    shape, ground, cams, text = rig_report(scene, VirtualRigParams(views=12, resolution=32))
    assert ground is not None and "support plane" in text and "outside-in, 12 views" in text
    path = tmp_path / "standing.ply"
    write_scene(scene, path)
    png = tmp_path / "out" / "rig.png"
    png.parent.mkdir()
    cmd = [sys.executable, "-m", "harness", "diagnose", str(path), "--method", "virtual-rig:views=12,resolution=32",
           "--no-references", "--n-train", "2", "--significance-side", "32", "--longest-side", "32",
           "--picture", str(png), "--json"]
    out = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    report = json.loads(out.stdout)["virtual_rig"]
    assert report["picture"] == str(png) and len(report["cameras"]) == 12
    from PIL import Image

    with Image.open(png) as im:
        assert im.size == (960, 500)
        colours = np.unique(np.asarray(im.convert("RGB")).reshape(-1, 3), axis=0)
        assert len(colours) > 50  # splats and cameras drawn, not a blank canvas


def test_diagnose_refuses_a_picture_it_cannot_write(tmp_path):
    cmd = [sys.executable, "-m", "harness", "diagnose", "luigi", "--method", "virtual-rig",
           "--picture", str(tmp_path / "rig.jpg")]
    out = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True)
    assert out.returncode == 2 and "Traceback" not in out.stderr
    assert "--picture" in out.stderr and ".png" in out.stderr and len(out.stderr.strip().splitlines()) == 1
