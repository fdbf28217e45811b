"""The plots of a run, each registered once like a table: what it draws, from which rows, into ``plots/``.

    register_plot("curves", draw=draw_curves, title="Quality against the pruning ratio, per scene")

* ``draw(df, ctx) -> [paths] | Missing``: the PNG files it wrote under ``ctx.out`` (``<run>/plots``),
  or :class:`~harness.report.tabledata.Missing` saying in one line why these results draw nothing.
  ``ctx`` (:class:`PlotContext`) holds the run folder, ``out``, the stored renders (``images``), the
  held-out view protocol the rows are of, and ``first_view``: the words a figure of the first held-out
  view appends to its title.
* ``rows``: ``"primary"`` — the rows of the run's primary held-out view protocol (titles name it) —
  or ``"all"`` (a plot that picks its own, such as the captured views' ``photos``).

Built-ins: ``curves`` (:mod:`.curves`), ``figure1`` and ``figure3`` (:mod:`.figures`), ``photos``
(:mod:`.photofigure`). Third-party packages add plots through the ``harness.plots`` entry-point group
(a module whose import calls :func:`register_plot`); a config's ``plots:`` and ``harness tables
--plots`` name them, and the report page shows what each drew.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from harness.core.registry import RegistrationError, Registry
from harness.report.tabledata import Missing, Written

ENTRY_POINT_GROUP = "harness.plots"


@dataclass(frozen=True)
class PlotContext:
    """Where a plot reads and writes: ``run_dir``, ``out`` (its ``plots/``), ``images`` (the renders a
    run stores) and ``protocol``, the held-out view protocol of the rows it is given ("" if none)."""

    run_dir: Path
    protocol: str = ""

    @property
    def out(self) -> Path:
        return self.run_dir / "plots"

    @property
    def images(self) -> Path:
        return self.run_dir / "images"

    @property
    def first_view(self) -> str:
        return f" — first held-out view ({self.protocol})" if self.protocol else ""


@dataclass(frozen=True)
class PlotSpec:
    name: str
    draw: Callable
    title: str
    rows: str = "primary"


PLOT_SPECS: Registry[PlotSpec] = Registry("plot", modules=(__name__,), group=ENTRY_POINT_GROUP)


def register_plot(name: str, *, draw: Callable, title: str, rows: str = "primary") -> PlotSpec:
    """Register plot ``name`` (module docstring)."""
    where = f"plot {name!r}"
    if not callable(draw):
        raise RegistrationError(where, f"draw must be a function draw(df, ctx), got {type(draw).__name__}")
    if not isinstance(title, str) or not title:
        raise RegistrationError(where, "title must be a sentence saying what the plot shows")
    if rows not in ("primary", "all"):
        raise RegistrationError(where, f"rows must be 'primary' or 'all', got {rows!r}")
    spec = PlotSpec(name, draw, title, rows)
    PLOT_SPECS.add(name, spec, same=lambda a, b: (a.title, a.draw.__qualname__) == (b.title, b.draw.__qualname__))
    return spec


def __getattr__(name: str):
    """``PLOTS``: the plots a config or ``harness tables --plots`` can name (built-ins and plugins')."""
    if name == "PLOTS":
        return tuple(PLOT_SPECS.names())
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def write_plots(df: pd.DataFrame, run_dir: str | Path, names) -> Written:
    """Draw each named plot, in registration order; one that draws nothing is a line of ``missing``
    (``plot <name> not drawn: <why>``)."""
    from harness.report.summary import protocol_subsets

    protocol, _, primary = protocol_subsets(df)[0]
    w = Written()
    specs = [s for s in PLOT_SPECS if s.name in set(names)]
    if not specs:
        return w
    import matplotlib

    # labels are text, never markup: a scene labelled '$\x$' is drawn as written, not parsed as TeX
    with matplotlib.rc_context({"text.parse_math": False}):
        for spec in specs:
            rows, ctx = (df, PlotContext(Path(run_dir))) if spec.rows == "all" else \
                (primary, PlotContext(Path(run_dir), protocol))
            got = spec.draw(rows, ctx)
            if isinstance(got, Missing):
                w.missing.append(f"plot {spec.name} not drawn: {got.reason}")
            else:
                w.paths += list(got)
    return w


# --------------------------------------------------------------------------- the built-in plots
def _curves(df: pd.DataFrame, ctx: PlotContext):
    from harness.report.curves import plot_curves

    return plot_curves(df, ctx.out, ctx.protocol) or Missing("no measured default variant")


def _figure1(df: pd.DataFrame, ctx: PlotContext):
    from harness.report.figures import draw_figure1

    return draw_figure1(df, ctx)


def _figure3(df: pd.DataFrame, ctx: PlotContext):
    from harness.report.figures import draw_figure3

    return draw_figure3(df, ctx)


def _photos(df: pd.DataFrame, ctx: PlotContext):
    from harness.report.photofigure import write_photo_figures

    return write_photo_figures(df, ctx.run_dir) or Missing(
        "no stored render of a view with a captured photo (scenes with a capture, under the `real` protocol)")


register_plot("curves", draw=_curves, title="Quality against the pruning ratio (and the pruned file's size), per scene")
register_plot("figure1", draw=_figure1, title="The paper's method at increasing pruning, τ = score at the cut (Fig. 1)")
register_plot("figure3", draw=_figure3, title="Without and with the Beta model at 20 % pruning (Fig. 3)")
register_plot("photos", draw=_photos, rows="all",
              title="A held-out view of a real capture: photo, unpruned and pruned renders")
