"""What a **cold** run of a config costs, before running it: work units per stage × unit costs.

Counting follows the runner's stages (:mod:`harness.run.runner`) and reads no more than headers
(costing, below, also looks at the scenes present from the views a run makes):

* **load** — one per (scene, frame): reading the file, ``read_splat · N`` (serial, in the driver;
  hashing the files, ~0.5 s per GB, is not counted).
* **score** — one task per distinct (scene, frame, method, resolved params) (the cache key's
  inputs); a camera-aware pruner renders its training views: LightGS-like ones (no
  ``iterations`` parameter) each of the ``n_train`` views once, ConfSplat-like ones each view once
  to set up plus one view per iteration: ``cost = k_m · renders · mean render(N, P_train)``, with
  ``P_train`` the training view resized to the method's ``train_longest_side``. Camera-free
  pruners cost ``score_splat[m] · N``, but those that render a virtual rig of their own:
  ``k_m · Σ render`` over its views.
* **prune** — one selection per distinct (score task, ratio): ``select_splat · N`` (serial, driver).
* **render_ref** — one per (scene, frame, protocol, held-out view): ``pack + draw`` of the view (below).
* **view protocols** (:mod:`harness.views.protocols`): each protocol's views as its ``sizes`` says
  (``n_test`` views of the run's size unless it says otherwise). One that brings its own training
  set (``real``: a scene's capture, its held-out cameras at the capture's size capped at the
  photos') is measured with the masks of a second training set — a camera-aware pruner scores again
  on its training cameras (an extra score task and pruned sets), a camera-free one shares its
  scores — and views with photos are measured against them too: the metric passes again except
  the LPIPS trunk (its pass is shared), plus once per view for the unpruned render.
* **render+metrics** — one task per held-out view: the view is projected, sorted and packed once
  (``pack``), and each pruned set drawn from that packing, its splats filtered from it (``draw``
  at the set's keep fraction: the GL renderer's :meth:`~renderers.gl.PackedView.kept`), plus the
  metric passes of the config's metrics (:func:`metric_passes`: 3dgs = PSNR + SSIM + LPIPS; mpeg =
  4 PSNR-like passes on 8-bit images + 2 SSIM passes, YUV and occupancy-masked) plus
  :data:`IMAGE_OVERHEAD_S`; the task computes the view's LPIPS reference features once
  (``lpips_ref_px · W·H``; the runner splits views only when there are fewer than a few per
  worker). Pruned sets are counted as distinct (score task, ratio) pairs: an **upper bound**, since
  methods that keep identical splats share one entry (the default study measures 114 sets where
  this counts 130).

**What a view sees** (:mod:`harness.run.view_coverage`): a scene present here is looked at from
every view a run of the config makes — the fraction ``front`` of its splats in front of the camera,
the fraction ``visible`` drawn, and ``overdraw``, their footprints per image pixel — and

    pack = N·(c_front·front + c_vis·visible)
    draw(keep) = keep·(c_draw·N·visible + c_frag·overdraw·W·H) + c_img·W·H

(``harness bench calibrate`` measures the five units on one view; :mod:`harness.run.unit_costs`).
A view from inside a room packs and draws the third of the splats it sees, a close-up of a few
large splats shades hundreds of fragments per pixel; costing every view the whole scene and its
pixels alone (``c_N·N + c_P·W·H``) comes to 1.3× the default study's measured wall time (its
independent and real views 1.26× and 1.38×). An absent (assumed) scene's views are taken to see
what the calibration's view saw. Render-based scoring is costed the same way: a camera-aware
pruner's training renders each as its training view sees the scene at the method's size, a
virtual rig's (``virtual-rig``, ``betadesc-vr``) as its synthesised views do, times the
benchmark's multiple of one such render (``methods.json``).

Each protocol's share (:attr:`Estimate.protocols`) is what the results' rows time of its views:
the reference renders and every image's draw and metric passes (not the packing, the reference
features or the per-image overhead, which no row holds). Beyond the units, a run spends
:data:`DRIVER_CPU_S` in its driver (imports, hashing, the run record) and :data:`WORKER_CPU_S`
per worker that starts (torch, the LPIPS weights, numba's cached kernels; :data:`IN_PROCESS_CPU_S`
for one worker, which runs in the driver's process).

**Wall time on W workers** (one core each, parallel efficiency e; e = 1 for one worker, which runs
in-process): the pool stages run one after another — scoring, then the reference renders and view
tasks as one pipeline — each taking ``max(core_s / (W·e), longest task)``, plus the pool's start-up
once (:data:`POOL_START_S`: spawn, imports, JIT); the driver's stages (load, prune) are serial.
So doubling the workers halves a stage's wall time until its longest single task — camera-aware
scoring of the largest scene, or one view task of the largest — bounds it from below.
``harness bench calibrate --check RUN_DIR`` compares an estimate with what a finished run measured.

Scenes whose files are absent (the MPEG sequences are not public) are estimated from
:class:`~harness.run.scene_sizes.Assumptions`, and every row says whether it was read or assumed
(:mod:`harness.run.scene_sizes`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from harness.run.config import RunConfig
from harness.run.scene_sizes import Assumptions, SceneInfo, scene_info  # noqa: F401  (estimate's inputs)
from harness.run.unit_costs import UnitCosts, train_pixels

#: per pool stage of the GPU model (:mod:`harness.run.estimate_device`): spawning workers, importing
#: torch/lpips, numba's first compile (default study on a busy 2-core machine: its first score results
#: came after ~15 s, its first reference renders after ~20 s)
STARTUP_S = 20.0
#: per measured image, work outside the timed render and metrics: reading and unpacking the mask,
#: PNGs, cache writes, the driver. Fitted with :data:`WORKER_CPU_S` and :data:`IN_PROCESS_CPU_S` to
#: three cold runs of one-thread workers on this machine, with the units of ``calibrate-cpu.json``
#: (bonsai-7k-mini, 256 px), CPU-s beyond the driver and the units: ci.yaml in-process (104 images
#: at 128 px: 3.7 = I + 104·o), ci.yaml on two workers (10.7 = 2·W + 104·o) and the default study
#: on luigi and grape-small on two workers (1,696 images at 256 px: 29.1 = 2·W + 1,696·o); so
#: o = 0.012 s, W = 4.75 s, I = 2.5 s
IMAGE_OVERHEAD_S = 0.012
#: CPU seconds of a run's driver beyond its stages' units: imports, configuration, hashing the
#: scene files, the run record (ci.yaml's cached rerun, which computes nothing: 2.0 CPU-s)
DRIVER_CPU_S = 2.0
#: CPU seconds of a spawned pool worker starting: imports (the harness, torch, numba), the LPIPS
#: weights, numba's cached kernels, each method's first call — one thread per worker (fitted with
#: :data:`IMAGE_OVERHEAD_S`). A worker of two threads spends about twice the CPU seconds for the same
#: work (torch's threads wait busily: ci.yaml in one worker, 26.0 CPU-s with two threads, 12.9 with
#: one), which the estimate, made for one-core workers, does not count
WORKER_CPU_S = 4.75
#: the same for one worker, which runs in the driver's process (its modules are loaded already)
IN_PROCESS_CPU_S = 2.5
#: wall seconds of the pool starting, once per run (the executor keeps its pool from the first pool
#: stage to the end): the workers start side by side, each on its own core; in-process (one worker)
#: the same imports happen in the first task. ci.yaml cold, one worker: its score and render stages
#: took 2.6 s more wall than their tasks' seconds
POOL_START_S = 3.0
#: parallel efficiency of a local pool of one-thread workers, one per core: the share of the pool's
#: core-time its tasks use. Two cold runs of the default study on this machine's 2 cores used 97 % and
#: 98 % of them (2,670 CPU-s in 22 min 54 s; 1,824 CPU-s in 930 s); 2 workers ran
#: ``study/scaling.yaml``'s stages 1.78× as fast as one (``harness bench executors``: 0.89, a small
#: study whose last long tasks run alone, and whose in-process run starts no pool — both counted apart
#: here, by the longest task and :data:`POOL_START_S`/:data:`WORKER_CPU_S`). 0.95 lies between, nearer
#: the studies that fill their pool
DEFAULT_EFFICIENCY = 0.95
#: stages the runner runs as one pipeline (a view's pruned sets start once its reference is drawn)
PIPELINED = ("render_ref", "render+metrics")
STAGES = ("load", "score", "prune", "render_ref", "render+metrics")
SERIAL = ("load", "prune")


@dataclass
class Stage:
    name: str
    units: int = 0
    core_s: float = 0.0
    longest_s: float = 0.0
    detail: dict = field(default_factory=dict)

    def add(self, units: int, core_s: float, longest_s: float = 0.0) -> None:
        self.units += units
        self.core_s += core_s
        self.longest_s = max(self.longest_s, longest_s)


@dataclass
class Estimate:
    stages: dict[str, Stage]
    scenes: list[dict]
    passes: dict[str, int]
    notes: list[str] = field(default_factory=list)
    #: core-seconds of each held-out view protocol's reference renders and its images' draws and metric
    #: passes (what the results' rows time: module docstring)
    protocols: dict[str, float] = field(default_factory=dict)

    @property
    def core_s(self) -> float:
        """The stages' core-seconds (the units of work; :meth:`cpu_s` adds the fixed overheads)."""
        return sum(s.core_s for s in self.stages.values())

    def cpu_s(self, workers: int) -> float:
        """CPU seconds of the whole run on ``workers`` workers: the stages' plus the driver's and each
        worker's start-up (:data:`DRIVER_CPU_S`, :data:`WORKER_CPU_S`)."""
        return self.core_s + DRIVER_CPU_S + (IN_PROCESS_CPU_S if workers == 1 else WORKER_CPU_S * workers)

    def stage_walls(self, workers: int, efficiency: float) -> dict[str, float]:
        """Projected wall seconds of each stage the runner times on ``workers`` one-core workers
        (``load``, ``score``, ``prune``, ``render_metrics``: the pipelined :data:`PIPELINED`); the
        pool's start-up (:data:`POOL_START_S`) falls on the first pool stage with work. One worker
        runs in-process: no parallel loss (efficiency 1)."""
        e = 1.0 if workers == 1 else efficiency
        render = [self.stages[n] for n in PIPELINED]
        pool = {"score": (self.stages["score"].core_s, self.stages["score"].longest_s, self.stages["score"].units),
                "render_metrics": (sum(s.core_s for s in render), max(s.longest_s for s in render),
                                   sum(s.units for s in render))}
        out = {n: self.stages[n].core_s for n in SERIAL}
        started = False
        for name, (core_s, longest_s, units) in pool.items():
            out[name] = max(core_s / (workers * e), longest_s) if units else 0.0
            if units and not started:
                out[name] += POOL_START_S
                started = True
        return out

    def wall_s(self, workers: int, efficiency: float) -> float:
        """Projected wall seconds on ``workers`` one-core workers (module docstring)."""
        return sum(self.stage_walls(workers, efficiency).values())

    def nodes(self, hours: float, cores: int, efficiency: float) -> tuple[int, int | None]:
        """(nodes by CPU-hours = ceil(core_s / (hours · cores · e)), the fewest nodes whose
        projected wall time fits in ``hours`` — None when the serial stages and longest tasks alone
        take longer)."""
        by_cpu = max(1, math.ceil(self.core_s / (hours * 3600 * cores * efficiency)))
        for n in range(by_cpu, by_cpu * 64 + 1):
            if self.wall_s(n * cores, efficiency) <= hours * 3600:
                return by_cpu, n
        return by_cpu, None


# --------------------------------------------------------------------------- counting and costing
def metric_passes(names) -> dict[str, int]:
    """Passes per measured image: ``lpips`` (LPIPS-VGG trunk), ``ssim`` (3-plane SSIM) and ``psnr``
    (a PSNR-like pass: squared errors, 8-bit quantisation, colour conversion), each metric's as
    registered (its ``cost``, :mod:`harness.metrics.registry`)."""
    from harness.metrics.registry import METRICS, PASS_KINDS

    out = dict.fromkeys(PASS_KINDS, 0)
    for n in names:
        out[METRICS.get(n).cost] += 1
    return out


def _score_cost(mv, spec, n: int, train, units: UnitCosts, notes: set, seen=None,
                protocol: str = "") -> tuple[float, int]:
    """(core-seconds, renders) of one score task on a frame of ``n`` splats; ``seen``: the scene's
    views (:class:`~harness.run.view_coverage.SceneCoverage`), ``protocol`` one whose masks the
    task's training set makes."""
    if "cameras" in spec.needs:
        return _aware_cost(mv, n, train, units, notes, seen, protocol)
    if units.aware.get(mv.method, (None, ""))[1] == "rig":
        return _rig_cost(mv, n, units, seen)
    unit = units.score_splat.get(mv.method)
    if unit is None and units.score_splat:
        unit = max(units.score_splat.values())
        notes.add(f"{mv.method}: no scoring benchmark; costed like the costliest camera-free method")
    return (unit or 0.0) * n, 0


def _rig_cost(mv, n: int, units: UnitCosts, seen) -> tuple[float, int]:
    """A camera-free method that renders a virtual rig of its own: its views, each rendered once."""
    px = int(mv.params.resolution) ** 2
    covs = (seen.of_virtual_rig(mv.params) if seen is not None else None) or [None] * int(mv.params.views)
    return units.aware[mv.method][0] * sum(units.render_view(n, px, c) for c in covs), len(covs)


def _aware_cost(mv, n: int, train, units: UnitCosts, notes: set, seen, protocol: str) -> tuple[float, int]:
    """A camera-aware method: its training renders (module docstring), each as its view sees the scene."""
    iters = getattr(mv.params, "iterations", None)
    shape = "views" if iters is None else "iterations"
    renders = len(train) + (int(iters) if iters is not None else 0)
    k = units.aware.get(mv.method, (None, shape))[0]
    if k is None and units.aware:
        k = next((k for k, s in units.aware.values() if s == shape), 1.0)
        notes.add(f"{mv.method}: no scoring benchmark; costed like a benchmarked {shape}-shaped camera-aware method")
    side = int(getattr(mv.params, "train_longest_side", 0) or 0)
    px = [train_pixels(s, side) for s in train]
    covs = seen.of_training(protocol, side) if seen is not None else []
    covs = covs if len(covs) == len(px) else [None] * len(px)
    mean = sum(units.render_view(n, p, c) for p, c in zip(px, covs)) / max(1, len(px))
    return (k or 0.0) * renders * mean, renders


@dataclass
class _Costing:
    """What every scene of an estimate is costed with: unit costs, the metric passes per pixel of a
    measured image (``per_px``), of a reference's LPIPS features (``ref_px``) and against a photo
    (``gt_px``: the passes again but the LPIPS trunk, shared, plus OM-PSNR), and the notes."""

    u: UnitCosts
    per_px: float
    ref_px: float
    gt_px: float
    notes: set


def estimate(config: RunConfig, infos: list[SceneInfo], units: UnitCosts | None) -> Estimate:
    """Counts per stage of a cold run of ``config`` on ``infos``; with ``units`` also core-seconds
    and the longest single task of each stage (``units=None``: counts only)."""
    u = units or UnitCosts(0, 0, 0, 0, 0, 0, 0, 0, {}, {})
    passes = metric_passes(config.protocol.metrics)
    cost = _Costing(u, passes["lpips"] * u.lpips_px + passes["ssim"] * u.ssim_px + passes["psnr"] * u.psnr_px,
                    u.lpips_ref_px if passes["lpips"] else 0.0,
                    passes["ssim"] * u.ssim_px + (passes["psnr"] + 1) * u.psnr_px, set())
    st = {n: Stage(n) for n in STAGES}
    st["score"].detail = {"training_renders": 0, "camera_aware_tasks": 0}
    st["render+metrics"].detail = {"view_tasks": 0, **{f"{k}_passes": 0 for k in passes}}
    per_protocol: dict[str, float] = {p.name: 0.0 for p in config.protocols}
    specs = {s.name: s for s in config.scenes}
    rows = [_cost_scene(config, specs[info.name], info, st, cost, per_protocol) for info in infos]
    for k, v in passes.items():
        st["render+metrics"].detail[f"{k}_passes"] = v * st["render+metrics"].units
    return Estimate(st, rows, passes, sorted(cost.notes), per_protocol)


def _cost_scene(config: RunConfig, spec, info: SceneInfo, st: dict, cost: _Costing, per_protocol: dict) -> dict:
    """Add every frame of one scene to the stages and its views' core-seconds to ``per_protocol``;
    returns the scene's row."""
    tasks = _score_tasks(config, spec, info, cost.notes)
    keeps = [1.0 - r for _, _, rs in tasks.values() for r in rs]
    protos = info.view_protocols(config.protocols[0].name)
    by_proto = {p: _keeps(config, spec, tasks, p) for p in set(protos)}
    before = {k: (s.units, s.core_s) for k, s in st.items()}
    for n in info.splats:
        for proto, core_s in _cost_frame(st, n, info, tasks, [by_proto[p] for p in protos], cost, protos):
            per_protocol[proto] = per_protocol.get(proto, 0.0) + core_s
    return _scene_row(info, st, before, len(keeps))


def _score_tasks(config: RunConfig, spec, info: SceneInfo, notes: set) -> dict[str, tuple]:
    """The distinct score tasks of a scene: (method, params) -> (variant, pruner, ratios); a
    camera-aware pruner without training cameras is skipped (a note says so)."""
    from methods.registry import get_pruner

    tasks: dict[str, tuple] = {}
    for mv in (m for m in config.methods if m.scenes is None or spec.name in m.scenes):
        pruner = get_pruner(mv.method)
        if "cameras" in pruner.needs and not info.every_train():
            notes.add(f"{spec.name}: {mv.method} needs training cameras and is skipped")
            continue
        key = f"{mv.method}|{sorted(mv.params.to_dict().items())!r}"
        prev = tasks.get(key, (mv, pruner, ()))
        tasks[key] = (prev[0], pruner, tuple(dict.fromkeys(prev[2] + tuple(mv.ratios))))
    return tasks


def _keeps(config: RunConfig, spec, tasks: dict, protocol: str) -> list[float]:
    """Keep fractions of the distinct pruned sets measured under ``protocol`` (a method entry's
    ``protocols``), one per (score task, ratio)."""
    sets = {}
    for mv in (m for m in config.methods if (m.scenes is None or spec.name in m.scenes) and m.measures(protocol)):
        key = f"{mv.method}|{sorted(mv.params.to_dict().items())!r}"
        if key in tasks:
            sets.update({(key, r): 1.0 - r for r in mv.ratios})
    return list(sets.values())


def _cost_frame(st: dict, n: int, info: SceneInfo, tasks: dict, keeps: list[list[float]], cost: _Costing,
                protos: list[str]) -> list[tuple[str, float]]:
    """Add one frame of ``n`` splats to the stages: its load; per training set (the scene's, and each
    one a protocol brings: :mod:`harness.run.plan`) its score tasks and selections; per held-out view
    its reference render and one view task measuring the pruned sets of its protocol (``keeps``:
    their keep fractions, per view of :meth:`SceneInfo.view_protocols`, whose protocol ``protos``
    names); views with photos are also measured against them. Returns (protocol, core-seconds) of
    each view's reference render and task."""
    u = cost.u
    sets = [(info.train, info.views, False)] * bool(info.views) + [(o.train, o.views, o.photos) for o in info.own]
    st["load"].add(1, u.read_splat * n)
    first, out, index = 0, [], dict.fromkeys(protos, 0)
    for j, (train, views, photos) in enumerate(sets):
        for mv, pruner, rs in tasks.values():
            aware = "cameras" in pruner.needs
            if (j and not aware) or (aware and not train):
                continue  # a camera-free pruner's scores serve every training set
            core_s, renders = _score_cost(mv, pruner, n, train, u, cost.notes, info.seen, protos[first])
            st["score"].add(1, core_s, core_s)
            st["score"].detail["training_renders"] += renders * aware
            st["score"].detail["camera_aware_tasks"] += aware
            st["prune"].add(len(rs), u.select_splat * n * len(rs), u.select_splat * n)
        for (w, h), kept, proto in zip(views, keeps[first:first + len(views)], protos[first:first + len(views)]):
            px, seen = w * h, _seen(info, proto, index)
            ref = u.render_view(n, px, seen)
            st["render_ref"].add(1, ref, ref)
            out.append((proto, ref))
            if not kept:
                continue
            extra = cost.gt_px * px if photos else 0.0
            image = [u.draw_view(n, px, seen, k) + cost.per_px * px + extra for k in kept]
            ref_cost = cost.ref_px * px + (extra + 2 * cost.ref_px * px) * photos  # + photo features, gt
            # one task per view: packed once, each set drawn; the rows time the draws and metric passes
            task = u.pack_view(n, seen) + ref_cost + sum(image) + IMAGE_OVERHEAD_S * len(kept)
            st["render+metrics"].add(len(kept), task, task)
            st["render+metrics"].detail["view_tasks"] += 1
            out.append((proto, sum(image)))
        first += len(views)
    return out


def _seen(info: SceneInfo, protocol: str, index: dict):
    """The coverage of the next view of ``protocol`` on the scene (None: not looked at); advances ``index``."""
    i = index[protocol]
    index[protocol] += 1
    covs = info.seen.of_views(protocol) if info.seen is not None else []
    return covs[i] if i < len(covs) else None


def _scene_row(info: SceneInfo, st: dict, before: dict, n_sets: int) -> dict:
    """The scene's row of the estimate: what was read or assumed, and its share of each stage."""
    sizes = sorted(set(info.every_view()))
    return {"scene": info.name, "status": info.status, "note": info.note, "frames": len(info.splats),
            "splats": round(sum(info.splats) / max(1, len(info.splats))),
            "views": len(info.every_view()),
            "train_views": len(info.every_train()),
            "size": "/".join(f"{w}×{h}" for w, h in sizes[:3]) + ("/…" if len(sizes) > 3 else ""),
            "score_tasks": st["score"].units - before["score"][0], "sets": n_sets,
            "images": st["render+metrics"].units - before["render+metrics"][0],
            "core_s": sum(s.core_s - before[k][1] for k, s in st.items())}
