"""Unit costs of a run's work, in core-seconds, read from the benchmark files of this machine.

Everything :mod:`harness.run.estimate` multiplies by a count comes from here, each number with the
file and field it was read from (``sources``), so the estimate says what it stands on.

=================  =====================================================  ==============================
unit               meaning (core-seconds = CPU seconds of one core)       anchor
=================  =====================================================  ==============================
``render_splat``   per splat of a GL render (projection, SH, sort,        ``calibrate-cpu.json``, else
                   upload, draw): ``c_N = c_pack + c_draw``               ``render-*.json`` with the most
``pack_splat``     its part done once per view (projection, SH, sort,     splats, ``backends.gl.``
                   packing): ``c_pack``                                   ``cpu_seconds_per_view`` (below)
``render_px``      per pixel of a GL render (fill, read-back): ``c_P``
``lpips_px``       LPIPS-VGG of one pruned image, per pixel               ``metrics.json`` ``lpips_cached_per_pruned_s``
``lpips_ref_px``   LPIPS reference features of a view task, per pixel     ``metrics.json``
                                                                          ``lpips_reference_features_s``
``ssim_px``        one SSIM pass (3 planes), per pixel                    ``metrics.json`` ``ssim_per_image_s``
``psnr_px``        one PSNR pass, per pixel                               ``metrics.json`` ``psnr_per_image_s``
``score_splat[m]`` camera-free scoring of method m, per splat             ``methods.json``
                                                                          ``scoring.<m>.cpu_s / splats``
``aware[m]``       camera-aware scoring: multiple of one training render  ``methods.json`` (see below)
                   (and a virtual rig's: multiple of one of its renders)
``front_splat`` …  the view-coverage units (below)                        ``calibrate-cpu.json``
``select_splat``   prune selection (threshold + mask), per splat          ``prune.json`` ``stages_cpu_s.select``
``read_splat``     reading a scene file, per splat                        ``read.json`` ``steps.read_ply.seconds``
=================  =====================================================  ==============================

**Render split.** A GL render costs ``c_N·N + c_P·W·H``. The benchmarks render at one size, so
the split between the two terms is fixed by :data:`SPLAT_SHARE`: in the file with the most splats
(bonsai-7k, 1.16 M, a room seen from inside) the per-splat work (projection, SH, sort, upload) is
65 % of the CPU time at 1024×768 — measured by the default study, whose pruned renders of the same
scene at 384×288 (7× fewer pixels) took 1.0–1.1 s in a one-thread worker against 1.54 CPU-s here.
Both terms come from that file. The other files are reported beside it: bonsai-7k-mini's (an orbit
close-up, measured with two threads on a busy machine) implies 4× the per-pixel cost, while one-thread ``--calibrate``
runs on it measured 0.3–0.55 µs per pixel: per-pixel cost depends on overdraw and load, so an estimate for unseen
content carries that spread. ``--calibrate`` measures both terms directly (two sizes).

**Measured split.** ``harness bench calibrate --device cpu`` (``calibrate-cpu.json``) measures
``c_pack`` (a view packed), ``c_draw`` and ``c_P`` (the packed view drawn at two sizes) and the
metric passes at the study's image size, with one thread and in CPU seconds, as a study's workers
run; when the file is there its units replace the others' (``sources`` says so). Without it,
``c_pack`` is :data:`PACK_SHARE` of ``c_N`` (measured: 0.4–0.6 µs per splat packed against
0.55–0.65 µs per splat drawn, numpy projection, one thread).

**View coverage.** The same calibration measures the units of what a view sees
(:mod:`harness.run.view_coverage`), on its view of the scene: ``front_splat`` and ``visible_splat``
(the view packed, and packed again 16× zoomed in: as many splats in front, few visible),
``image_px`` (a packing of no splat drawn), ``draw_splat`` and ``fragment_px`` (the packed view
drawn at the size and at twice it: as many splats, four times the pixels, more footprint pixels).
Not at half the size: llvmpipe draws the one-pixel splats of a small image at a cost of their
own (bonsai-7k-mini at 128 and 256 px gives about 3× the per-fragment cost that 256 and 512 px give, which
the default study's draws, 128–384 px views of five scenes, do not bear out). With them
(:attr:`UnitCosts.covered`) every view is costed by its coverage; the calibration's view (``seen``)
stands for a view of unknown content. ``aware[m]`` and a virtual rig's multiple are then taken
against renders of that view's coverage.

**Metrics** ran with ``threads`` torch threads; core-seconds = wall × threads (an upper bound:
the threads were busy). Costs scale with pixels: ``unit_px = seconds × threads / (W₀·H₀)``.

**Camera-aware scoring** is a number of training renders: LightGS-like pruners (no ``iterations``
parameter) render each of the ``n_train`` views once; ConfSplat-like ones (an ``iterations``
parameter) render every view once to set up and then one view per iteration (forward + backward).
``aware[m] = cpu_s / (units₀ · render(N₀, P₀))`` with ``units₀`` = the benchmark's 48 views (+ its
iterations) and ``P₀`` its training views' pixels at the method's ``train_longest_side``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

from harness.run.view_coverage import Coverage, is_rig_shaped

#: share of the per-splat work in the GL render of the largest benchmark scene (module docstring)
SPLAT_SHARE = 0.65
#: share of the per-splat work done once per view (projection, sort, packing) when no
#: calibrate-cpu.json measures it (module docstring)
PACK_SHARE = 0.45
#: ``harness bench calibrate --device cpu``'s units (module docstring)
CPU_CALIBRATION = "calibrate-cpu.json"
CALIBRATED = ("render_splat", "pack_splat", "render_px", "lpips_px", "lpips_ref_px", "ssim_px", "psnr_px")
#: the view-coverage units, when the calibration measured them
COVERAGE_UNITS = ("front_splat", "visible_splat", "draw_splat", "fragment_px", "image_px")
#: the training-view benchmark's rig (harness bench methods: 48 views at 1024×768)
BENCH_TRAIN = (48, (1024, 768))

#: values of the committed results/bench files (2-core reference machine, 2026-11-22), used for a
#: file that is missing here
BUILTIN = {
    "render": [{"file": "render-bonsai-7k.json", "splats": 1157141, "size": (1024, 768), "cpu": 1.539011165},
               {"file": "render-bonsai-7k-mini.json", "splats": 272956, "size": (1024, 768), "cpu": 2.357269626}],
    "metrics": {"image": (1024, 768), "threads": 2, "lpips_cached_per_pruned_s": 1.879102732,
                "lpips_reference_features_s": 1.625053145, "ssim_per_image_s": 0.386854762,
                "psnr_per_image_s": 0.013411087, "peak_rss_mb": 3520.8},
    "methods": {"splats": 272956, "train_views": 48, "scoring": {
        "betadesc": {"cpu_s": 0.391295, "params": {}}, "betadesc-nobeta": {"cpu_s": 0.222749, "params": {}},
        "betadesc-nodesc": {"cpu_s": 0.042496, "params": {}},
        "betadesc-nodesc-nobeta": {"cpu_s": 0.038971, "params": {}},
        "confsplat": {"cpu_s": 71.270740, "needs": ["cameras"], "params": {"longest_side": 128, "iterations": 600}},
        "lightgs": {"cpu_s": 21.065218, "needs": ["cameras"], "params": {"longest_side": 512}},
        "opacity": {"cpu_s": 0.004390, "params": {}}, "random": {"cpu_s": 0.000795, "params": {}},
        "volume": {"cpu_s": 0.009450, "params": {}}}},
    "prune": {"splats": 1157141, "select": 0.119567710},
    "read": {"splats": 1157141, "read_ply": 0.287273504},
}


@dataclass
class UnitCosts:
    render_splat: float
    render_px: float
    lpips_px: float
    lpips_ref_px: float
    ssim_px: float
    psnr_px: float
    select_splat: float
    read_splat: float
    score_splat: dict[str, float]
    #: camera-aware: (k, shape) with shape "views" (LightGS-like) or "iterations" (ConfSplat-like)
    aware: dict[str, tuple[float, str]]
    rss_px: float = 0.0  # peak memory of a metrics worker per pixel (MiB), metrics.json peak_rss_mb
    sources: dict[str, str] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    #: the part of ``render_splat`` spent once per view, projecting, sorting and packing (``c_pack``)
    pack_splat: float = 0.0
    #: the view-coverage model (``calibrate-cpu.json``; 0: not calibrated, the model above is used):
    #: per splat in front of the camera, per visible splat packed, per visible splat drawn, per
    #: fragment (footprint pixel) and per image pixel (:mod:`harness.run.view_coverage`)
    front_splat: float = 0.0
    visible_splat: float = 0.0
    draw_splat: float = 0.0
    fragment_px: float = 0.0
    image_px: float = 0.0
    #: the coverage of the calibration's view: what a view of unknown content is taken to see
    seen: Coverage = Coverage(1.0, 1.0, 0.0)

    def render(self, splats: float, pixels: float) -> float:
        """Core-seconds of one GL render of ``splats`` splats at ``pixels`` pixels: pack + draw."""
        return self.render_splat * splats + self.render_px * pixels

    def pack(self, splats: float) -> float:
        """Core-seconds of projecting, sorting and packing a view of ``splats`` splats (once per view)."""
        return self.pack_splat * splats

    def draw(self, splats: float, pixels: float) -> float:
        """Core-seconds of drawing ``splats`` splats of a packed view at ``pixels`` pixels."""
        return (self.render_splat - self.pack_splat) * splats + self.render_px * pixels

    @property
    def covered(self) -> bool:
        """Whether the view-coverage units were measured (else :meth:`pack_view` and :meth:`draw_view`
        fall back to :meth:`pack` and :meth:`draw`)."""
        return self.draw_splat > 0.0

    def pack_view(self, splats: float, seen: Coverage | None) -> float:
        """Core-seconds of packing a view of ``splats`` splats that sees ``seen`` (None: the
        calibration view's coverage): ``c_front·N·front + c_vis·N·visible``."""
        s = seen or self.seen
        if not self.covered:
            return self.pack(splats)
        return splats * (self.front_splat * s.front + self.visible_splat * s.visible)

    def draw_view(self, splats: float, pixels: float, seen: Coverage | None, keep: float = 1.0) -> float:
        """Core-seconds of drawing the kept fraction ``keep`` of a packed view of ``splats`` splats at
        ``pixels`` pixels: ``keep·(c_draw·N·visible + c_frag·overdraw·W·H) + c_img·W·H`` (the pruned
        splats taken to be as visible and as large as the others)."""
        s = seen or self.seen
        if not self.covered:
            return self.draw(splats * keep, pixels)
        return keep * (self.draw_splat * splats * s.visible + self.fragment_px * s.overdraw * pixels) \
            + self.image_px * pixels

    def render_view(self, splats: float, pixels: float, seen: Coverage | None) -> float:
        """Core-seconds of one whole render (pack + draw) of a view that sees ``seen``."""
        return self.pack_view(splats, seen) + self.draw_view(splats, pixels, seen)


def _read(folder: Path, name: str, notes: list[str]):
    path = folder / name
    try:
        return json.loads(path.read_text())
    except FileNotFoundError:
        notes.append(f"{path} is missing: using the built-in value of the reference machine "
                     "(run `harness bench ...` or --calibrate to measure here)")
    except (OSError, ValueError) as err:
        notes.append(f"{path} is unreadable ({type(err).__name__}): using the built-in value")
    return None


def _render_points(folder: Path, notes: list[str]) -> list[dict]:
    pts = []
    for path in sorted(folder.glob("render-*.json")):
        try:
            gl = json.loads(path.read_text())["backends"]["gl"]
            if gl.get("available") and gl.get("cpu_seconds_per_view"):
                pts.append({"file": path.name, "splats": int(gl["splats"]), "size": tuple(gl["size"]),
                            "cpu": float(gl["cpu_seconds_per_view"])})
        except (OSError, ValueError, KeyError, TypeError):
            notes.append(f"{path}: no usable gl entry, ignored")
    if pts:
        return pts
    notes.append(f"no {folder}/render-*.json with a gl entry: using the built-in render costs")
    return [{**p, "file": f"built-in {p['file']}"} for p in BUILTIN["render"]]


def _px(size) -> int:
    return int(size[0]) * int(size[1])


def train_pixels(size, longest_side: int) -> float:
    """Pixels of a training view of ``size`` resized to ``longest_side`` (0: as given)."""
    w, h = size
    s = longest_side / max(w, h) if longest_side else 1.0
    return round(w * s) * round(h * s)


def from_bench(folder: Path) -> UnitCosts:
    """Unit costs from ``folder`` (``results/bench``); a missing file falls back to :data:`BUILTIN`."""
    notes: list[str] = []
    src: dict[str, str] = {}
    pts = _render_points(folder, notes)
    big = max(pts, key=lambda p: p["splats"])
    c_n = SPLAT_SHARE * big["cpu"] / big["splats"]
    c_p = (1 - SPLAT_SHARE) * big["cpu"] / _px(big["size"])
    src["render_splat"] = f"{big['file']} backends.gl.cpu_seconds_per_view × {SPLAT_SHARE} / splats"
    src["render_px"] = f"{big['file']} backends.gl.cpu_seconds_per_view × {1 - SPLAT_SHARE:.2f} / (W·H)"
    for p in pts:
        if p is not big:
            other = max(p["cpu"] - c_n * p["splats"], 0.0) / _px(p["size"])
            notes.append(f"{p['file']} implies {other * 1e6:.2g} µs per pixel against {c_p * 1e6:.2g} from "
                         f"{big['file']}: per-pixel render cost depends on the content's overdraw")

    m = _read(folder, "metrics.json", notes) or BUILTIN["metrics"]
    tag = "metrics.json" if m is not BUILTIN["metrics"] else "built-in metrics.json"
    per = float(m.get("threads", 1)) / _px(m["image"])
    units = {k: float(m[f]) * per for k, f in (("lpips_px", "lpips_cached_per_pruned_s"),
                                                ("lpips_ref_px", "lpips_reference_features_s"),
                                                ("ssim_px", "ssim_per_image_s"), ("psnr_px", "psnr_per_image_s"))}
    for k, f in (("lpips_px", "lpips_cached_per_pruned_s"), ("lpips_ref_px", "lpips_reference_features_s"),
                 ("ssim_px", "ssim_per_image_s"), ("psnr_px", "psnr_per_image_s")):
        src[k] = f"{tag} {f} × threads / (W·H)"
    rss_px = float(m.get("peak_rss_mb", 0.0)) / _px(m["image"])

    p = _read(folder, "prune.json", notes)
    if p is not None:
        e = p["end_to_end"]
        prune = {"splats": e["splats_in"], "select": e["stages_cpu_s"]["select"]}
    else:
        prune = BUILTIN["prune"]
    src["select_splat"] = ("prune.json" if p else "built-in prune.json") + " end_to_end.stages_cpu_s.select / splats_in"
    r = _read(folder, "read.json", notes)
    read = {"splats": r["splats"], "read_ply": r["steps"]["read_ply"]["seconds"]} if r else BUILTIN["read"]
    src["read_splat"] = ("read.json" if r else "built-in read.json") + " steps.read_ply.seconds / splats"

    src["pack_splat"] = f"{PACK_SHARE} × render_splat (no {CPU_CALIBRATION})"
    costs = UnitCosts(render_splat=c_n, render_px=c_p, select_splat=prune["select"] / prune["splats"],
                      read_splat=read["read_ply"] / read["splats"], score_splat={}, aware={}, rss_px=rss_px,
                      sources=src, notes=notes, pack_splat=PACK_SHARE * c_n, **units)
    _calibrated(costs, folder)  # before the camera-aware multiples, which divide by a training render's cost
    meth = _read(folder, "methods.json", notes) or BUILTIN["methods"]
    add_methods(costs, meth, "methods.json" if meth is not BUILTIN["methods"] else "built-in methods.json")
    return costs


def _calibrated(costs: UnitCosts, folder: Path) -> None:
    """The units ``calibrate-cpu.json`` measured replace the benchmarks' (module docstring)."""
    path = folder / CPU_CALIBRATION
    try:
        cal = json.loads(path.read_text())
        units = {k: float(cal["units"][k]) for k in CALIBRATED}
    except FileNotFoundError:
        return
    except (OSError, ValueError, KeyError, TypeError) as err:
        costs.notes.append(f"{path} is unreadable ({type(err).__name__}): the benchmarks' units are used")
        return
    if all(isinstance(cal["units"].get(k), (int, float)) for k in COVERAGE_UNITS) and isinstance(cal.get("seen"), dict):
        units.update({k: float(cal["units"][k]) for k in COVERAGE_UNITS})
        costs.seen = Coverage(**{k: float(cal["seen"][k]) for k in ("front", "visible", "overdraw")})
    for k, v in units.items():
        setattr(costs, k, v)
        costs.sources[k] = f"{CPU_CALIBRATION} units.{k} ({cal.get('scene', '?')}, {'×'.join(map(str, cal['size']))})"


def add_methods(costs: UnitCosts, meth: dict, tag: str) -> None:
    """Scoring units of every method in a ``methods.json`` payload (module docstring)."""
    n0 = float(meth["splats"])
    views0 = int(meth.get("train_views", BENCH_TRAIN[0]))
    size0 = tuple(meth.get("train_resolution", BENCH_TRAIN[1]))
    for name, rec in meth["scoring"].items():
        cpu = float(rec.get("cpu_s", rec.get("wall_s", 0.0)))
        params = rec.get("params", {})
        if "cameras" in rec.get("needs", []):
            side = int(params.get("train_longest_side", params.get("longest_side", 0)))
            iters = params.get("iterations")
            renders = views0 + (int(iters) if iters is not None else 0)
            k = cpu / (renders * costs.render_view(n0, train_pixels(size0, side), None))
            costs.aware[name] = (k, "iterations" if iters is not None else "views")
            costs.sources[f"aware[{name}]"] = (f"{tag} scoring.{name}.cpu_s / ({renders} training renders of "
                                               f"{int(n0):,} splats at {side or max(size0)} px)")
            continue
        costs.score_splat[name] = cpu / n0
        costs.sources[f"score[{name}]"] = f"{tag} scoring.{name}.cpu_s / {int(n0):,} splats"
        if costs.covered and is_rig_shaped(params):  # renders a rig of its own: costed per render, as above
            renders, px = int(params["views"]), int(params["resolution"]) ** 2
            costs.aware[name] = (cpu / (renders * costs.render_view(n0, px, None)), "rig")
            costs.sources[f"aware[{name}]"] = (f"{tag} scoring.{name}.cpu_s / ({renders} renders of its virtual rig, "
                                               f"{int(n0):,} splats at {params['resolution']} px)")
