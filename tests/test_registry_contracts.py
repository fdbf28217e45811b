"""The contract every registered metric, renderer, table, plot and view protocol keeps, checked on each
one its registry lists — built-ins and installed plugins alike, so a new one is covered without
touching this file (as ``tests/test_pruner_contract.py`` does for pruners; the suite's own fakes,
registered by other test modules, are left out).

* **metric**: on two random images a finite number inside its registered range, the same twice;
  identical images score at least as well as different ones (+inf where registered so); its table
  heading shows its direction; a ``gt_`` twin against the photo exists.
* **renderer**: an (H, W, 3) float32 finite image; an empty scene is the background; what it declares
  (``alpha``, ``pack``) it does: alpha in [0, 1], a packed view drawn equals the render.
* **table**: built from small results a :class:`Table` (whose markdown, LaTeX and CSV can be
  written) or a :class:`Missing` with a one-line reason; from no results a Missing, never an exception.
* **plot**: drawn into a run folder, PNG files inside ``plots/`` or a Missing with a one-line reason;
  from no results a Missing.
* **view protocol**: for a small scene, views that are Cameras of at most the run's size, finite,
  with distinct names, the same twice, counted as ``sizes`` says — or nothing (None, or NoViews
  saying why); its notes are a sentence and its parameters parse from their defaults.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from harness.core.cameras import Camera
from harness.metrics.registry import METRICS, is_gt
from harness.report.plots import PLOT_SPECS
from harness.report.results import to_frame
from harness.report.tabledata import Missing, Table
from harness.report.tables import TABLE_SPECS, build_tables
from harness.views.protocols import PROTOCOL_SPECS, HeldOut, NoViews, ViewRequest, protocol
from renderers import RENDERERS, capabilities
from tests.scene_factory import random_scene


def _own(specs, fn=lambda s: s) -> list:
    """Registered entries whose code is not the test suite's own."""
    return [s for s in specs if not getattr(fn(s), "__module__", "").split(".")[0].startswith("test")]


def _one_line(reason: str) -> bool:
    return isinstance(reason, str) and bool(reason.strip()) and "\n" not in reason


# --------------------------------------------------------------------------- metrics
def _metrics():
    return [m for m in _own(METRICS, lambda m: m.compute) if not is_gt(m.name)]


def _values(name: str, a, b):
    from harness.metrics.suite import compare_images

    spec = METRICS.get(name)
    if spec.check is not None:
        from harness.core.errors import InputError

        try:
            spec.check()
        except InputError as err:
            pytest.skip(f"{name} cannot run here: {err}")
    return compare_images(a, b, names=(name,))[name]


@pytest.fixture(scope="module")
def images():
    rng = np.random.default_rng(5)
    a = rng.random((24, 32, 3)).astype(np.float32)
    b = np.clip(a + rng.normal(0, 0.08, a.shape), 0, 1).astype(np.float32)
    return a, b


@pytest.mark.parametrize("spec", _metrics(), ids=lambda s: s.name)
def test_metric_values_are_finite_in_range_and_repeatable(spec, images):
    a, b = images
    v = _values(spec.name, a, b)
    assert isinstance(v, float) and math.isfinite(v), f"{spec.name}: {v!r}"
    assert spec.problem(v) is None, spec.problem(v)
    assert _values(spec.name, a, b) == v


@pytest.mark.parametrize("spec", _metrics(), ids=lambda s: s.name)
def test_identical_images_score_best(spec, images):
    a, b = images
    same, other = _values(spec.name, a, a), _values(spec.name, a, b)
    if spec.inf_if_identical:
        assert same == math.inf
    assert same >= other if spec.higher_is_better else same <= other
    assert spec.problem(same) is None


@pytest.mark.parametrize("spec", list(METRICS), ids=lambda s: s.name)
def test_every_metric_says_how_tables_show_it(spec):
    assert spec.heading.endswith("(↑)" if spec.higher_is_better else "(↓)") and spec.label
    assert 0 <= spec.digits <= 12 and spec.valid_range[0] <= spec.valid_range[1]
    if not is_gt(spec.name):
        assert METRICS.get("gt_" + spec.name).is_gt


# --------------------------------------------------------------------------- renderers
def _renderer(spec):
    try:
        return spec.make("cpu")
    except Exception as err:  # noqa: BLE001  an EGL context or a library this machine lacks
        pytest.skip(f"renderer {spec.name} cannot start here: {type(err).__name__}: {str(err)[:120]}")


@pytest.fixture(scope="module")
def small_view():
    from harness.views.rigs import make_rig

    scene = random_scene(200, sh_degree=1, seed=2)
    return scene, make_rig("orbit", scene, n_train=0, n_test=1, longest_side=24).test[0]


@pytest.mark.parametrize("spec", list(RENDERERS), ids=lambda s: s.name)
def test_renderer_contract(spec, small_view):
    scene, cam = small_view
    r = _renderer(spec)
    try:
        img = r.render(scene, cam, background=(0.2, 0.4, 0.6))
        assert img.dtype == np.float32 and img.shape == (cam.height, cam.width, 3) and np.isfinite(img).all()
        empty = r.render(scene.subset(np.zeros(len(scene), bool)), cam, background=(0.2, 0.4, 0.6))
        np.testing.assert_allclose(empty, np.broadcast_to([0.2, 0.4, 0.6], empty.shape), atol=1e-6)
        caps = capabilities(r)
        assert caps <= {"alpha", "pack", "batch", "device_batch"} and ("batch" not in caps or "pack" in caps)
        assert "device_batch" not in caps or "pack" in caps
        if "alpha" in caps:
            image, alpha = r.render_with_alpha(scene, cam, (0.0, 0.0, 0.0))
            assert alpha.shape == (cam.height, cam.width) and 0 <= alpha.min() and alpha.max() <= 1 + 1e-6
        if "pack" in caps:
            np.testing.assert_array_equal(r.draw(r.pack(scene, cam), (0.2, 0.4, 0.6)), img)
        if "batch" in caps:
            packed = r.pack(scene, cam)
            for got in r.draw_many([packed, packed.kept(np.zeros(len(scene), bool))], (0.2, 0.4, 0.6))[:1]:
                np.testing.assert_array_equal(got, img)
        if "device_batch" in caps:
            images, _ = r.draw_many_on([r.pack(scene, cam)], "cpu", (0.2, 0.4, 0.6))
            np.testing.assert_array_equal(images[0].numpy(), img)
    finally:
        r.close()


# --------------------------------------------------------------------------- tables and plots
def _results():
    rows = []
    for method in ("betadesc", "betadesc-nodesc", "betadesc-nobeta", "betadesc-nodesc-nobeta", "lightgs", "random"):
        for ratio in (0.1, 0.2, 0.3):
            for v in range(3):
                p = 30.0 - 20 * ratio + v + (method == "lightgs")
                rows.append(dict(run="t", scene="s", label="s", kind="object-centric", frame="", method=method,
                                 variant="default", params="{}", ratio=ratio, keep=round(1 - ratio, 9),
                                 protocol="rig", view=f"v{v}", status="ok", psnr=p, ssim=0.9 - ratio / 10,
                                 lpips=0.05 + ratio / 10, splats_in=100, splats_out=int(100 * (1 - ratio)),
                                 bytes=1000 - 10 * int(100 * ratio), score_s=0.5, render_s=0.1, metrics_s=0.1))
    return to_frame(rows)


@pytest.mark.parametrize("spec", _own(TABLE_SPECS, lambda s: s.build), ids=lambda s: s.name)
def test_table_contract(spec, tmp_path):
    from harness.report.formats import to_latex, to_markdown

    for df in (_results(), _results().iloc[:0]):
        t = build_tables(df, [spec.name])[spec.name]
        assert isinstance(t, (Table, Missing)), type(t)
        if isinstance(t, Missing):
            assert _one_line(t.reason), t.reason
            continue
        assert len(df), f"{spec.name} made a table of no results"
        assert to_markdown(t, spec.title) and to_latex(t.disp, spec.title, t.notes) and t.tidy.to_csv()


@pytest.mark.parametrize("spec", _own(PLOT_SPECS, lambda s: s.draw), ids=lambda s: s.name)
def test_plot_contract(spec, tmp_path):
    from harness.report.plots import write_plots

    for df, run in ((_results(), tmp_path / "full"), (_results().iloc[:0], tmp_path / "empty")):
        run.mkdir()
        w = write_plots(df, run, [spec.name])
        assert len(w.paths) + len(w.missing) >= 1
        for line in w.missing:
            assert line.startswith(f"plot {spec.name} not drawn: ") and _one_line(line)
        for p in map(Path, w.paths):
            assert p.parent == run / "plots" and p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert not w.paths or len(df), f"{spec.name} drew a plot of no results"


# --------------------------------------------------------------------------- view protocols
def _request(scene, **over) -> ViewRequest:
    from harness.views.rigs import image_size, make_rig

    rig = make_rig("orbit", scene, n_train=4, n_test=3, longest_side=48)
    base = dict(name="s", dataset=None, rig="orbit", kind="object-centric", n_train=4, n_test=3, longest_side=48,
                aspect=None, seed=0, scene=lambda: scene, held_out=lambda: list(rig.test),
                view_size=image_size(48, 4 / 3))
    return ViewRequest(**{**base, **over})


@pytest.mark.parametrize("spec", _own(PROTOCOL_SPECS, lambda s: s.views), ids=lambda s: s.name)
def test_protocol_contract(spec):
    assert _one_line(spec.notes) and spec.params.parse({}) is not None
    p = protocol(spec.name)
    request = _request(random_scene(300, seed=4))
    try:
        got = p.views(request)
    except NoViews as why:
        assert _one_line(str(why)), why
        return
    if got is None:
        return
    assert isinstance(got, HeldOut) and got.test
    for c in got.test + (got.train or []):
        assert isinstance(c, Camera) and max(c.width, c.height) <= request.longest_side
        assert np.isfinite(c.rotation).all() and np.isfinite(c.center).all()
    assert len({c.name for c in got.test}) == len(got.test)
    again = p.views(request)
    assert [c.to_dict() for c in again.test] == [c.to_dict() for c in got.test]  # the same views twice
    sizes = p.sizes(request)
    assert sizes is not None and sizes.test == [(c.width, c.height) for c in got.test]
    assert set(got.photos) <= {c.name for c in got.test}
