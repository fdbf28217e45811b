"""The torch reference rasterizer against a dense numpy re-implementation of the classic 3DGS forward pass.

The numpy renderer below is written independently of ``renderers/`` (float64, one splat at a time over
the whole pixel grid, constants typed from graphdeco ``auxiliary.h``), so agreement is real evidence.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from harness.core.cameras import Camera
from harness.core.scene import GaussianScene
from renderers.projection import SplatTensors, project_gaussians
from renderers.reference import ReferenceRenderer, rasterize

C0 = 0.28209479177387814
C1 = 0.4886025119029199
C2 = [1.0925484305920792, -1.0925484305920792, 0.31539156525252005, -1.0925484305920792, 0.5462742152960396]
C3 = [-0.5900435899266435, 2.890611442640554, -0.4570457994644658, 0.3731763325901154,
      -0.4570457994644658, 1.445305721320277, -0.5900435899266435]


# ----------------------------------------------------------------------------- dense numpy truth
def _sh_color(coeffs, d):
    x, y, z = d
    b = [C0]
    if len(coeffs) > 1:
        b += [-C1 * y, C1 * z, -C1 * x]
    if len(coeffs) > 4:
        b += [C2[0] * x * y, C2[1] * y * z, C2[2] * (2 * z * z - x * x - y * y), C2[3] * x * z,
              C2[4] * (x * x - y * y)]
    if len(coeffs) > 9:
        b += [C3[0] * y * (3 * x * x - y * y), C3[1] * x * y * z, C3[2] * y * (4 * z * z - x * x - y * y),
              C3[3] * z * (2 * z * z - 3 * x * x - 3 * y * y), C3[4] * x * (4 * z * z - x * x - y * y),
              C3[5] * z * (x * x - y * y), C3[6] * x * (x * x - 3 * y * y)]
    return np.maximum(np.asarray(b) @ coeffs + 0.5, 0.0)


def _rotmat(q):
    n = np.linalg.norm(q)
    w, x, y, z = q / n if n > 0 else (1.0, 0.0, 0.0, 0.0)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def dense_render(scene, cam, bg=(0, 0, 0), opac=None, early_stop=False, footprint="box"):
    """Image (H, W, 3) and per-splat Σα·T, Σo·T, hits, by brute force over every pixel."""
    n, w, h = len(scene), cam.width, cam.height
    rot, tr, centre = cam.world_to_cam[:3, :3], cam.world_to_cam[:3, 3], cam.center
    fx, fy, cx, cy = cam.fx, cam.fy, cam.cx, cam.cy
    o_all = 1 / (1 + np.exp(-scene.opacity_logit.astype(np.float64))) if opac is None else opac
    sh = np.concatenate([scene.sh_dc[:, None], scene.sh_rest], 1).astype(np.float64)
    splats = []
    for i in range(n):
        mu = scene.means[i].astype(np.float64)
        x, y, z = rot @ mu + tr
        if not z > 0.2:
            continue
        s = np.exp(scene.scales_log[i].astype(np.float64))
        m = _rotmat(scene.quats[i].astype(np.float64)) * s
        v = rot @ (m @ m.T) @ rot.T
        lx, ly = 0.5 * w / fx, 0.5 * h / fy
        tx = min(max(x / z, -(cx / fx + 0.3 * lx)), (w - cx) / fx + 0.3 * lx) * z
        ty = min(max(y / z, -(cy / fy + 0.3 * ly)), (h - cy) / fy + 0.3 * ly) * z
        jac = np.array([[fx / z, 0, -fx * tx / z**2], [0, fy / z, -fy * ty / z**2]])
        cov = jac @ v @ jac.T + 0.3 * np.eye(2)
        det = cov[0, 0] * cov[1, 1] - cov[0, 1] ** 2
        if not (np.isfinite(cov).all() and det > 0):
            continue
        mid = 0.5 * (cov[0, 0] + cov[1, 1])
        r = math.ceil(3 * math.sqrt(mid + math.sqrt(max(0.1, mid * mid - det))))
        d = (mu - centre) / np.linalg.norm(mu - centre)
        splats.append((z, i, fx * x / z + cx - 0.5, fy * y / z + cy - 0.5, np.linalg.inv(cov), r,
                       _sh_color(sh[i, : {1: 1, 4: 4, 9: 9, 16: 16}[sh.shape[1]]], d), o_all[i]))
    splats.sort(key=lambda t: (t[0], t[1]))
    py, px = np.mgrid[0:h, 0:w].astype(np.float64)
    col, trans, done = np.zeros((h, w, 3)), np.ones((h, w)), np.zeros((h, w), bool)
    at, ot, hits = np.zeros(n), np.zeros(n), np.zeros(n, np.int64)
    for _, i, mx, my, con, r, c, o in splats:
        dx, dy = px - mx, py - my
        power = -0.5 * (con[0, 0] * dx * dx + con[1, 1] * dy * dy) - con[0, 1] * dx * dy
        alpha = np.minimum(0.99, o * np.exp(power))
        m = (power <= 0) & (alpha >= 1 / 255)
        if footprint == "box":
            m &= (np.abs(dx) <= r) & (np.abs(dy) <= r)
        else:  # graphdeco getRect: whole 16x16 tiles
            gx, gy = (w + 15) // 16, (h + 15) // 16
            x0, x1 = (min(gx, max(0, int((mx - r) // 16))), min(gx, max(0, int((mx + r + 15) // 16))))
            y0, y1 = (min(gy, max(0, int((my - r) // 16))), min(gy, max(0, int((my + r + 15) // 16))))
            m &= (px >= 16 * x0) & (px < 16 * x1) & (py >= 16 * y0) & (py < 16 * y1)
        if early_stop:
            m &= ~done
            stop = m & (trans * (1 - alpha) < 1e-4)
            done |= stop
            m &= ~stop
        a = np.where(m, alpha, 0.0)
        col += (a * trans)[..., None] * c
        at[i] += (a * trans).sum()
        ot[i] += (o * trans * m).sum()
        hits[i] += m.sum()
        trans = trans * (1 - a)
    return col + trans[..., None] * np.asarray(bg, np.float64), at, ot, hits


# ----------------------------------------------------------------------------- scenes
def make_scene(n, degree=0, seed=0, spread=1.0, log_scale=-1.6):
    rng = np.random.default_rng(seed)
    k = {0: 0, 1: 3, 2: 8, 3: 15}[degree]
    return GaussianScene.from_arrays(
        means=rng.normal(size=(n, 3)) * spread,
        scales_log=rng.normal(log_scale, 0.5, size=(n, 3)),
        quats=rng.normal(size=(n, 4)),
        opacity_logit=rng.normal(0.5, 1.5, size=n),
        sh_dc=rng.normal(size=(n, 3)),
        sh_rest=rng.normal(0, 0.3, size=(n, k, 3)),
    )


def cam(w=45, h=37, eye=(0.3, -0.4, -4.0), fov=55.0, target=(0, 0, 0)):
    return Camera.look_at(eye, target, fov_y_deg=fov, width=w, height=h)


def check(scene, camera, tol=1e-5, **kw):
    bg = kw.pop("bg", (0.1, 0.3, 0.9))
    out = rasterize(scene, camera, bg, device="cpu", stats=True, **kw)
    img, at, ot, hits = dense_render(scene, camera, bg, early_stop=kw.get("early_stop", False),
                                     footprint=kw.get("footprint", "box"))
    diff = np.abs(out.image.numpy() - img).max()
    assert diff <= tol, diff
    np.testing.assert_allclose(out.alpha_t.numpy(), at, atol=1e-4, rtol=1e-4)
    np.testing.assert_allclose(out.opacity_t.numpy(), ot, atol=1e-4, rtol=1e-4)
    np.testing.assert_array_equal(out.hits.numpy(), hits)
    return out, img


# ----------------------------------------------------------------------------- agreement
@pytest.mark.parametrize("degree", [0, 1, 2, 3])
@pytest.mark.parametrize("seed", [0, 1])
def test_matches_dense_numpy(degree, seed):
    scene = make_scene(60, degree, seed)
    _, img = check(scene, cam())
    assert (img.sum(-1) != np.dot((0.1, 0.3, 0.9), (1, 1, 1))).mean() > 0.3  # the scene is really drawn


@pytest.mark.parametrize("early_stop,footprint", [(True, "tile"), (True, "box"), (False, "tile")])
def test_graphdeco_modes_match_dense(early_stop, footprint):
    scene = make_scene(150, 1, seed=3, log_scale=-1.2)
    scene.opacity_logit[:] = 4.0  # opaque overlaps, so T crosses 1e-4 in many pixels
    check(scene, cam(50, 40), early_stop=early_stop, footprint=footprint)


def test_float64_path_matches_tightly():
    scene = make_scene(40, 3, seed=5)
    st = SplatTensors.from_scene(scene, device="cpu", dtype=torch.float64)
    out = rasterize(st, cam(), (0.2, 0.2, 0.2))
    img = dense_render(scene, cam(), (0.2, 0.2, 0.2))[0]
    assert out.image.dtype == torch.float64
    assert np.abs(out.image.numpy() - img).max() < 1e-7


def test_small_budget_gives_the_same_image():
    scene = make_scene(80, 2, seed=7)
    a = rasterize(scene, cam(), device="cpu").image
    b = rasterize(scene, cam(), device="cpu", budget=1).image
    c = rasterize(scene, cam(), device="cpu", tile=8).image
    assert torch.allclose(a, b, atol=1e-6) and torch.allclose(a, c, atol=1e-6)


def test_projection_fields():
    scene = make_scene(30, 0, seed=2)
    p = project_gaussians(scene, cam(), device="cpu")
    assert p.means2d.dtype == torch.float32 and p.ids.dtype == torch.long
    # the pixel convention: a splat on the optical axis lands at (cx - 0.5, cy - 0.5)
    one = GaussianScene.from_arrays(np.zeros((1, 3)), np.full((1, 3), -2.0), [[1, 0, 0, 0]], [0.0], [[0, 0, 0]])
    c = Camera.look_at((0, 0, -3), (0, 0, 0), width=40, height=30)
    q = project_gaussians(one, c, device="cpu")
    np.testing.assert_allclose(q.means2d.numpy()[0], (c.cx - 0.5, c.cy - 0.5), atol=1e-5)
    np.testing.assert_allclose(q.colors.numpy()[0], 0.5, atol=1e-6)


# ----------------------------------------------------------------------------- gradients
def test_gradcheck_float64():
    scene = make_scene(6, 1, seed=11, spread=0.5, log_scale=-1.0)
    st = SplatTensors.from_scene(scene, device="cpu", dtype=torch.float64)
    c = cam(12, 10, eye=(0, 0, -3.0))
    rng = np.random.default_rng(0)
    opac = torch.tensor(rng.uniform(0.2, 0.8, 6), dtype=torch.float64, requires_grad=True)
    means = st.means.clone().requires_grad_(True)
    sh = st.sh.clone().requires_grad_(True)

    def f(o, mu, shc):
        s = SplatTensors(mu, st.scales_log, st.quats, st.opacity_logit, shc)
        return rasterize(s, c, (0.3, 0.1, 0.2), opacities=o, budget=12 * 16 * 16 * 2).image

    assert torch.autograd.gradcheck(f, (opac, means, sh), eps=1e-6, atol=1e-5, fast_mode=True)


def test_gradient_of_opacity_matches_finite_difference_float32():
    scene = make_scene(40, 0, seed=4)
    c = cam(32, 24)
    o = torch.sigmoid(torch.tensor(scene.opacity_logit)).clamp(0.05, 0.9).requires_grad_(True)
    loss = rasterize(scene, c, device="cpu", opacities=o).image.square().sum()
    (g,) = torch.autograd.grad(loss, o)
    with torch.no_grad():
        for i in np.argsort(-np.abs(g.numpy()))[:3]:
            e = torch.zeros_like(o)
            e[i] = 1e-2
            up = rasterize(scene, c, device="cpu", opacities=o + e).image.square().sum()
            dn = rasterize(scene, c, device="cpu", opacities=o - e).image.square().sum()
            assert abs(float((up - dn) / 2e-2) - float(g[i])) < 0.02 * abs(float(g[i])) + 1e-3


# ----------------------------------------------------------------------------- edge cases
def test_behind_camera_and_across_near_plane_are_culled():
    scene = make_scene(40, 0, seed=8, spread=0.6, log_scale=-1.0)
    c = Camera.look_at((0, 0, -0.5), (0, 0, 1), width=40, height=30)
    z = (scene.means.astype(np.float64) @ c.rotation.T + c.translation)[:, 2]
    assert (z < 0).any() and ((z > 0) & (z <= 0.2)).any() and (z > 0.2).any()
    out, _ = check(scene, c)
    front = rasterize(scene.subset(z > 0.2), c, (0.1, 0.3, 0.9), device="cpu").image
    assert torch.allclose(out.image, front, atol=1e-6)
    assert (out.hits.numpy()[z <= 0.2] == 0).all()


def test_very_large_and_very_small_scales():
    scene = make_scene(30, 2, seed=9)
    scene.scales_log[:5] = 3.0  # bigger than the view
    scene.scales_log[5:10] = -25.0  # far below a pixel: the 0.3 dilation alone sets the footprint
    scene.scales_log[10, 0] = 200.0  # overflows float32: dropped, never NaN
    out, _ = check(scene, cam())
    assert torch.isfinite(out.image).all() and out.hits[10] == 0
    p = project_gaussians(scene, cam(), device="cpu")
    small = np.isin(p.ids.numpy(), np.arange(5, 10))
    assert (p.radii.numpy()[small] == 3).all()  # ceil(3·sqrt(0.3 + sqrt(0.1)))


def test_quaternions_zero_norm_and_unnormalised():
    scene = make_scene(20, 0, seed=10)
    ident = scene.subset(np.arange(20))
    ident.quats[:] = (1, 0, 0, 0)
    zero = scene.subset(np.arange(20))
    zero.quats[:] = 0
    check(zero, cam())
    assert torch.equal(rasterize(zero, cam(), device="cpu").image, rasterize(ident, cam(), device="cpu").image)
    scaled = scene.subset(np.arange(20))
    scaled.quats *= 7.3
    a, b = rasterize(scene, cam(), device="cpu").image, rasterize(scaled, cam(), device="cpu").image
    assert torch.allclose(a, b, atol=1e-6)


def test_opacity_zero_and_one():
    scene = make_scene(30, 0, seed=12)
    bg = (0.25, 0.5, 0.75)
    img0 = rasterize(scene, cam(), bg, device="cpu", opacities=torch.zeros(30)).image
    assert torch.equal(img0, torch.tensor(bg).expand_as(img0))
    ones = np.ones(30)
    out = rasterize(scene, cam(), bg, device="cpu", opacities=torch.ones(30), stats=True)
    img, _, _, hits = dense_render(scene, cam(), bg, opac=ones)
    assert np.abs(out.image.numpy() - img).max() <= 1e-5
    np.testing.assert_array_equal(out.hits.numpy(), hits)
    scene.opacity_logit[:] = 1e4  # sigmoid → exactly 1, alpha clamps to 0.99
    check(scene, cam())


def test_empty_scene_returns_background():
    empty = make_scene(0)
    out = rasterize(empty, cam(), (0.1, 0.2, 0.3), device="cpu", stats=True)
    assert out.image.shape == (37, 45, 3)
    assert torch.equal(out.image, torch.tensor((0.1, 0.2, 0.3)).expand(37, 45, 3))
    assert out.hits.shape == (0,)
    r = ReferenceRenderer("cpu").render(empty, cam(), (1, 0, 0))
    assert r.dtype == np.float32 and (r == (1, 0, 0)).all()


def test_camera_inside_the_cloud():
    scene = make_scene(200, 1, seed=13, spread=2.0, log_scale=-1.3)
    c = Camera.look_at((0.05, 0.02, 0.0), (0, 0, 1), fov_y_deg=90, width=40, height=40)
    out, _ = check(scene, c)
    assert out.hits.sum() > 0 and torch.isfinite(out.image).all()


@pytest.mark.parametrize("w,h", [(1024, 8), (8, 1024)])
def test_extreme_aspect_ratios(w, h):
    scene = make_scene(40, 1, seed=14)
    c = Camera.look_at((0, 0, -4), (0, 0, 0), fov_y_deg=50 if h > w else 2, width=w, height=h)
    out, _ = check(scene, c)
    assert out.hits.sum() > 0


@pytest.mark.slow
def test_compiled_step_matches_dense():
    """The torch.compile'd block step (used automatically for big CPU renders) is the same math."""
    scene = make_scene(80, 3, seed=21)
    check(scene, cam(), compiled=True)
    check(scene, cam(50, 40), compiled=True, early_stop=True, footprint="tile")


def test_renderer_wrapper_defaults_follow_the_gl_conventions():
    scene = make_scene(50, 2, seed=22)
    r = ReferenceRenderer("cpu")
    img = r.render(scene, cam(), (0.1, 0.3, 0.9))
    dense = dense_render(scene, cam(), (0.1, 0.3, 0.9), early_stop=False, footprint="box")[0]
    assert img.dtype == np.float32 and img.shape == (37, 45, 3)
    assert np.abs(img - dense).max() <= 1e-5
    exact = ReferenceRenderer("cpu", early_stop=True, footprint="tile").render(scene, cam())
    assert np.abs(exact - dense_render(scene, cam(), early_stop=True, footprint="tile")[0]).max() <= 1e-5
    r.close()


def test_checkpointed_blocks_give_the_same_gradient():
    scene = make_scene(60, 1, seed=23)
    o = torch.sigmoid(torch.tensor(scene.opacity_logit)).requires_grad_(True)
    grads = []
    for ckpt in (True, False):
        img = rasterize(scene, cam(), device="cpu", opacities=o, checkpoint=ckpt, budget=4096).image
        grads.append(torch.autograd.grad(img.square().sum(), o)[0])
    assert grads[0].abs().sum() > 0
    assert torch.allclose(grads[0], grads[1], atol=1e-6)
