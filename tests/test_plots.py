"""Plots: near-identical points do not hijack the axis, legends sit outside, figure 1 gives the actual τ."""

from __future__ import annotations

import math

import numpy as np
import pytest
from PIL import Image

from harness.report import curves, drawing, plots
from harness.report.record import image_name
from harness.report.results import to_frame


def _rows(near=197.25):
    rows = []
    spec = {("random", 0.1): (36.0, 37.0), ("random", 0.3): (26.0, 27.0), ("lightgs", 0.1): (math.inf, near),
            ("lightgs", 0.3): (65.0, 66.0), ("betadesc", 0.1): (29.0, 30.0), ("betadesc", 0.3): (22.0, 21.0),
            ("betadesc", 0.5): (18.0, 19.0), ("betadesc", 0.7): (16.0, 15.0)}
    for (m, r), vals in spec.items():
        for v, p in enumerate(vals):
            rows.append(dict(run="t", scene="grape", label="grape-small", kind="object-centric", frame="", method=m,
                             variant="default", params="{}", ratio=r, keep=round(1 - r, 9), view=f"v{v}", status="ok",
                             psnr=p, ssim=0.99, lpips=0.01 * r, splats_in=100, splats_out=int(100 * (1 - r)),
                             tau=0.4 + r / 5 if m == "betadesc" else 0.0, score_s=0.1))
    return to_frame(rows)


@pytest.fixture
def figures(monkeypatch):
    """The figures plots would save, kept open for inspection."""
    saved = {}

    def keep(fig, path):
        saved[path.name] = fig
        return path

    monkeypatch.setattr(drawing, "save", keep)
    monkeypatch.setattr(drawing.pyplot(), "close", lambda fig=None: None)
    return saved


def test_a_near_identical_point_does_not_stretch_the_psnr_axis(figures, tmp_path):
    """Issue 16: one 192 dB point stretched grape-small's PSNR axis to 200."""
    curves.plot_curves(_rows(), tmp_path)
    fig = figures["curves_grape-small.png"]
    psnr = fig.axes[0]
    lo, hi = psnr.get_ylim()
    assert hi < 80 and lo > 10  # informative range 15..66 dB, plus headroom for the ▲ marks
    tri = [ln for ln in psnr.lines if ln.get_marker() == "^"]
    assert len(tri) == 1 and tri[0].get_ydata()[0] == pytest.approx(0.96)  # on the top edge, axis coordinates
    leg = fig.legends[0]
    assert "every view ≥ 100 dB" in leg.get_texts()[-1].get_text()


def test_a_high_but_informative_point_stays_on_the_scale(figures, tmp_path):
    curves.plot_curves(_rows(near=92.0).assign(psnr=lambda d: d["psnr"].replace(math.inf, 92.0)), tmp_path)
    assert figures["curves_grape-small.png"].axes[0].get_ylim()[1] > 92.0


def test_the_legend_is_outside_every_axis(figures, tmp_path):
    """Issue 16: luigi's legend hid a data point."""
    curves.plot_curves(_rows(), tmp_path)
    fig = figures["curves_grape-small.png"]
    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    box = fig.legends[0].get_window_extent(r)
    assert all(ax.legend_ is None for ax in fig.axes)
    for ax in fig.axes:
        assert box.x0 >= ax.get_window_extent(r).x1 - 1


def test_figure1_titles_give_the_actual_tau(figures, tmp_path):
    """Issue 16: figure 1 labelled its columns 'τ ≈ 0.1' while τ (the score at the cut) was 0.48."""
    df = _rows()
    d = tmp_path / "images" / "grape"
    d.mkdir(parents=True)
    img = Image.fromarray(np.full((8, 8, 3), 128, np.uint8))
    img.save(d / "input.png")
    for r in (0.1, 0.3, 0.5, 0.7):
        img.save(d / image_name("betadesc", "default", r))
    w = plots.write_plots(df, tmp_path, ["figure1"])
    assert w.missing == []
    fig = figures["figure1.png"]
    titles = [ax.get_title() for ax in fig.axes]
    assert titles[1] == "10% pruned\nτ = 0.420" and titles[4] == "70% pruned\nτ = 0.540"
    assert [ax.get_xlabel() for ax in fig.axes][1:] == ["τ = 0.420", "τ = 0.460", "τ = 0.500", "τ = 0.540"]
    assert "≈" not in "".join(titles)


def test_figure1_shows_no_empty_not_run_panels(figures, tmp_path):
    """Issue 23: a run of 10-30 % drew two 'not run' columns (50 %, 70 %) in figure 1 for every scene."""
    df = _rows()
    for scene, n in (("grape", 2), ("other", 1)):
        d = tmp_path / "images" / scene
        d.mkdir(parents=True)
        img = Image.fromarray(np.full((8, 8, 3), 128, np.uint8))
        img.save(d / "input.png")
        for r in (0.1, 0.3)[:n]:
            img.save(d / image_name("betadesc", "default", r))
    df = to_frame(df.to_dict("records") + [{**r, "scene": "other", "label": "other"} for r in df.to_dict("records")])
    assert plots.write_plots(df, tmp_path, ["figure1"]).missing == []
    fig = figures["figure1.png"]
    assert [ax.get_title() for ax in fig.axes[:3]] == ["unpruned", "10% pruned\nτ = 0.420", "30% pruned\nτ = 0.460"]
    assert len(fig.axes) == 2 * 3  # two scenes x (unpruned, 10 %, 30 %): no 50 / 70 % columns
    assert not any(t.get_text() == "not run" for ax in fig.axes for t in ax.texts)
    assert not fig.axes[5].get_frame_on()  # the cell one scene lacks is blank, without a frame


def test_a_plot_that_cannot_be_drawn_says_why(tmp_path):
    w = plots.write_plots(_rows(), tmp_path, ["figure1", "figure3"])
    assert w.paths == [] and len(w.missing) == 2
    assert w.missing[0].startswith("plot figure1 not drawn: no stored render of betadesc at 10% / 30% / 50% / 70%")
    assert w.missing[1].startswith("plot figure3 not drawn: no stored renders of betadesc-nobeta and betadesc at 20%")


def test_om_and_bytes_panels_when_the_results_carry_them(figures, tmp_path, monkeypatch):
    from harness.metrics.builtin import psnr_pair
    from harness.metrics.registry import METRICS, register_metric

    monkeypatch.setattr(METRICS, "_entries", dict(METRICS._entries))
    register_metric("psnr_om", label="OM-PSNR", compute=psnr_pair, higher_is_better=True, unit="dB", cost="psnr",
                    family="test", digits=2, masks="psnr")
    df = _rows().assign(psnr_om=lambda d: d["psnr"] - 1.0, bytes=lambda d: 1000 * (1 - d["ratio"]))
    curves.plot_curves(df, tmp_path)
    axes = figures["curves_grape-small.png"].axes
    assert [ax.get_ylabel() for ax in axes] == ["PSNR (↑)", "OM-PSNR (↑)", "LPIPS (↓)", "PSNR (↑)"]
    assert axes[-1].get_xlabel() == "pruned .ply size (MiB)"


def test_plots_name_the_protocol_they_show(figures, tmp_path):
    """Curves and figures are of the primary held-out view protocol, and say so."""
    df = to_frame([{**r, "protocol": p} for p in ("rig", "shifted") for r in _rows().to_dict("records")])
    plots.write_plots(df, tmp_path, ["curves"])
    assert "held-out views: rig" in figures["curves_grape-small.png"]._suptitle.get_text()
