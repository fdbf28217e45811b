"""Execute a run: load -> score -> prune -> render reference -> render pruned + metrics -> aggregate.

Every stage first asks the content-addressed cache (:mod:`harness.run.cache`) and computes only what is
missing, so a rerun with nothing changed recomputes nothing and a killed run resumes where it
stopped. Independent work (scores per (scene, method variant); views per (scene, frame, view)) runs
on a local process pool of ``workers`` spawned processes, each with ``cores // workers`` threads.

Deduplication: scores are computed once per (scene, method, resolved params) for all ratios; a
view's reference render and reference metric features once for all methods; a pruned set identical
to another (same keep-mask digest) is rendered and measured once per view.

Cache keys hold the code digests taken when the run starts; workers import the code when they
start (one pool per stage), so editing pruner/renderer/metric sources *during* a run can store a
result under the previous code's key. Rerun with ``--force`` after such edits.
"""

from __future__ import annotations

import functools
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from harness.metrics.registry import gt_names
from harness.run.cache import StageCache, digest_json, digest_mask
from harness.run.cache.versions import module_versions
from harness.run.config import RunConfig
from harness.run.config.keys import key_inputs
from harness.run.executors import Bars, Executor, LocalExecutor, Stage
from harness.run.plan import SceneItem, Skip, Versions, load_items, training_sets_for, variants_for
from harness.run.tasks import (
    MaskJob,
    ScoreTask,
    ViewTask,
    run_score,
    run_view,
)
from harness.run.toolkit import Toolkit
from harness.run.verify import (
    gt_check,
    mask_check,
    metrics_check,
    prune_check,
    render_ref_record_check,
    score_array_check,
    score_record_check,
)

#: tasks per worker below which views are split (see :meth:`Runner._view_stage`)
BALANCE = 4
#: fewest pruned sets in a split-off task: a task pays one reference feature pass (LPIPS-VGG) and one
#: projection of the view, as much as measuring about one pruned set
MIN_CHUNK = 8


def view_parts(jobs: list, views: int, slots: int) -> list[list]:
    """A view's pruned sets as one task, or, when ``views`` tasks cannot fill ``slots`` (the tasks
    wanted in flight), as near-equal chunks of at least :data:`MIN_CHUNK` sets, in order."""
    if views >= slots:
        return [jobs]
    parts = max(1, min(-(-slots // views), len(jobs) // MIN_CHUNK))
    cuts = [len(jobs) * k // parts for k in range(parts + 1)]  # sizes differ by at most one
    return [jobs[a:b] for a, b in zip(cuts, cuts[1:])]


@dataclass
class RunResult:
    out_dir: Path
    rows: list[dict]
    skips: list[Skip]
    errors: list[str]
    stage_s: dict[str, float]
    counts: dict[str, dict[str, int]]
    images: dict = field(default_factory=dict)  # (scene, method, variant, ratio) -> cache png path
    executor: dict = field(default_factory=dict)  # where the work ran (run.json)


def _renders(task: ViewTask) -> bool:
    """A view task renders (the GL renderer draws on the GPU) and measures with the metrics' torch
    forms on the run's device: on a GPU run it belongs to a device worker."""
    return True


def _where(item: SceneItem) -> str:
    """``scene`` or ``scene/frame``: how messages and task names point at a (scene, frame)."""
    return f"{item.spec.name}/{item.frame}" if item.frame else item.spec.name


class Runner:
    def __init__(self, config: RunConfig, *, out_dir: Path, cache_root: Path | str, workers: int = 1,
                 force: bool = False, toolkit: Toolkit | None = None, progress=None, log=print,
                 base_dir: Path | None = None, executor: Executor | None = None):
        self.config = config
        self.out_dir = Path(out_dir)
        self.cache = StageCache(cache_root, force=force, warn=lambda m: log(f"warning: {m}"))
        from harness.io.files import sweep_stale_temps

        sweep_stale_temps(self.cache.root, recursive=True)  # left by a killed run (kill -9 of a writer)
        self.workers = max(1, int(workers))
        self.toolkit = toolkit or Toolkit()
        self.progress = progress  # a harness.run.progress.StageProgress or None
        self.log = log
        self.base = Path(base_dir) if base_dir else Path.cwd()
        self.primary = config.protocols[0].name  # the run's first protocol: its views are the figures'
        #: where the work units run (the caller closes an executor it passed; ours is closed by run())
        self.executor = executor or LocalExecutor(self.workers, self.toolkit, device=config.protocol.device,
                                                  device_workers=config.executor.device_workers)
        self._own_executor = executor is None
        self.threads = getattr(self.executor, "threads", max(1, (os.cpu_count() or 1) // self.workers))
        self.stage_s: dict[str, float] = {}
        self.errors: list[str] = []

    # ------------------------------------------------------------------ execution helpers
    def _stages(self, *stages: Stage) -> list[list[dict]]:
        """Run the stages' tasks on the executor (one pipeline when it can), advancing their bars."""
        return self.executor.run(stages, Bars(self.progress))

    def _map(self, stage: str, fn, tasks: list, weight=lambda t: 1, on_device=lambda t: False):
        """Run ``fn`` over ``tasks`` on the executor, advancing the stage's bar."""
        return self._stages(Stage(stage, fn, tasks, weight, on_device))[0]

    def _timed(self, stage: str, fn, *args):
        t0 = time.perf_counter()
        try:
            return fn(*args)
        finally:
            self.stage_s[stage] = self.stage_s.get(stage, 0.0) + time.perf_counter() - t0

    # ------------------------------------------------------------------ stages
    def run(self) -> RunResult:
        from methods.registry import get_pruner

        try:
            return self._run(get_pruner)
        finally:
            if self._own_executor:
                self.executor.close()

    def _run(self, get_pruner) -> RunResult:
        t_all = time.perf_counter()
        self.toolkit.check_metrics(self.config.protocol.metrics)
        versions = Versions.of(self.toolkit)
        self.versions = versions

        def skipped(spec, reason):
            self.log(f"skip {spec.name}: {reason}")

        def noted(spec, text):
            self.log(f"note {spec.name}: {text}")

        items, skips = self._timed("load", load_items, self.config, self.cache, self.toolkit, versions,
                                   self.base, skipped, noted)
        self.errors += [f"scene {s.scene}: {s.reason}" for s in skips if s.status == "error"]
        self.items = items
        scores, skips2 = self._timed("score", self._score_stage, items, get_pruner)
        skips += skips2
        prunes = self._timed("prune", self._prune_stage, items, scores)
        self._timed("render_metrics", self._view_stage, items, prunes)
        rows, images = self._timed("aggregate", self._rows, items, scores, prunes, skips)
        self.stage_s["total"] = time.perf_counter() - t_all
        # content hashing of the inputs (every run; part of "load"): its cost, reported in run.json
        self.stage_s["hash_inputs"] = self.cache.files.seconds
        self.hashed_bytes = self.cache.files.hashed_bytes
        return RunResult(self.out_dir, rows, skips, self.errors, self.stage_s, self.cache.counts(), images,
                         executor=self.executor.describe())

    def _score_key(self, item: SceneItem, mv, spec, train=None) -> str:
        """Camera-aware pruners key on their training cameras (``train``: the item's rig views)."""
        aware = spec.wants_cameras(mv.params)
        cams = item.train_digest if train is None else digest_json([c.to_dict() for c in train])
        p = self.config.protocol
        return self.cache.key(
            "score", scene=item.digest, method=mv.method, params=mv.params.to_dict(),
            code=self.versions.pruner(mv.method), cameras=cams if aware else None,
            **key_inputs("score", p), **key_inputs("aware_score", p, unset=not aware),
        )

    def _score_stage(self, items, get_pruner):
        """{(item index, method key, training set): (score key, record)}, one per training set of the
        item's protocols (:meth:`SceneItem.train_sets`; a method that ignores cameras has one key for
        all of them, computed once); camera-aware without cameras -> skip."""
        out, skips, tasks, pending, hits = {}, [], [], {}, {}
        for i, item in enumerate(items):
            for mv in variants_for(item, self.config.methods):
                spec = get_pruner(mv.method)
                for ts, train in training_sets_for(item, mv).items():
                    if "cameras" in spec.needs and not train:
                        skips.append(Skip(item.spec.name, item.frame, mv.method, mv.variant,
                                          f"{mv.method} needs {', '.join(sorted(spec.needs))}: the scene has no "
                                          f"{ts} training cameras (give a rig or a cameras file with training views)"))
                        continue
                    key = self._score_key(item, mv, spec, train)
                    if key not in pending and key not in hits:
                        hits[key] = self._cached_scores(key, item.n_splats)
                    if hits.get(key) is not None:
                        out[(i, mv.key, ts)] = (key, hits[key])
                        continue
                    if key not in pending:
                        pending[key] = []
                        tasks.append(self._score_task(key, item, mv, spec, ts, train))
                    pending[key].append((i, mv.key, ts))
        if self.executor.parallel:  # camera-aware (rendering) and big scenes first, so the pool ends together
            cost = {k: items[ik[0][0]].n_splats * (10 if t.train else 1) for t, (k, ik) in zip(tasks, pending.items())}
            tasks.sort(key=lambda t: -cost[t.key])
        for res in self._map("score", run_score, tasks, on_device=lambda t: get_pruner(t.method).uses_device):
            rec = self._stored_scores(res, items[pending[res["key"]][0][0]].n_splats, items, pending[res["key"]])
            for ik in pending[res["key"]]:
                out[ik] = (res["key"], rec)
        return out, skips

    def _score_task(self, key: str, item: SceneItem, mv, spec, ts: str, train) -> ScoreTask:
        p = self.config.protocol
        return ScoreTask(self.cache.location, key, item.path, item.spec.lod, item.digest, mv.method, mv.params, p.seed,
                         [c.to_dict() for c in train] if spec.wants_cameras(mv.params) else None, p.device,
                         self.toolkit, label=f"{_where(item)} {mv.key}" + (f" ({ts} cameras)" if ts != "rig" else ""))

    def _stored_scores(self, res: dict, n: int, items, serves) -> dict:
        """The record of a score task that ran: its stored record when it and the array verify, else
        an ``error`` record (the error also listed with every (scene, method, ratios) it serves)."""
        rec = {"error": res["error"]} if res["error"] else self.cache.load_json(
            "score", res["key"], check=score_record_check(n))
        if not res["error"] and (rec is None or self.cache.load_array(
                "score", res["key"], check=score_array_check(n)) is None):
            rec = {"error": "the stored scores failed verification"}
        if "error" in rec:
            mvs = {m.key: m for m in self.config.methods}
            who = "; ".join(f"{_where(items[i])} {mk} (ratios {', '.join(format(r, 'g') for r in mvs[mk].ratios)})"
                            for i, mk in dict.fromkeys((i, mk) for i, mk, _ in serves))
            self.errors.append(f"score {who} [{res['key'][:12]}]: {rec['error']}")
        return rec

    def _cached_scores(self, key: str, n: int):
        """The score record when both it and its array pass verification (a hit), else None (a
        miss: whichever entry is bad was discarded with a warning, and both are recomputed)."""
        rec = None if self.cache.force else self.cache.get_json("score", key, count=False,
                                                                check=score_record_check(n))
        if rec is not None and self.cache.load_array("score", key, check=score_array_check(n)) is None:
            rec = None
        self.cache.count("score", rec is not None)
        return rec

    def _prune_stage(self, items, scores):
        """{(item index, method key, ratio): prune record with mask digest}."""
        from methods.targeting import select_by_ratio

        code = module_versions(("methods.targeting",))
        out, done = {}, {}
        for (i, mk, ts), (skey, srec) in scores.items():
            item = items[i]
            mv = next(m for m in self.config.methods if m.key == mk)
            if "error" in srec:
                continue
            arr = None
            n = item.n_splats
            for r in mv.ratios:
                if (skey, r) in done:  # the same scores under another training set
                    out[(i, mk, ts, r)] = done[(skey, r)]
                    continue
                key = self.cache.key("prune", score=skey, ratio=r, code=code)
                rec = self.cache.get_json("prune", key, count=False, check=prune_check(n, r))
                if rec is not None and self.cache.load_array(
                        "masks", rec["mask"], check=mask_check(n, rec["splats_out"], rec["mask"])) is None:
                    rec = None  # its mask was missing or bad (discarded): recompute both
                self.cache.count("prune", rec is not None)
                if rec is None:
                    if arr is None:
                        arr = self.cache.load_array("score", skey, check=score_array_check(n))
                        if arr is None:
                            self.errors.append(f"prune {_where(item)} {mv.key} ratio {r:g} [{key[:12]}]: "
                                               f"scores {skey[:12]} failed verification")
                            break
                    t0 = time.perf_counter()
                    sel = select_by_ratio(arr, r)
                    mask = digest_mask(sel.keep)
                    if self.cache.load_array("masks", mask, check=mask_check(n, sel.kept, mask)) is None:
                        self.cache.put_array("masks", mask, np.packbits(sel.keep))
                    rec = {"mask": mask, "tau": sel.tau, "tau_quantile": sel.tau_quantile,
                           "splats_out": sel.kept, "seconds": time.perf_counter() - t0}
                    self.cache.put_json("prune", key, rec)
                out[(i, mk, ts, r)] = done[(skey, r)] = rec
        return out

    def ref_key(self, item: SceneItem, cam) -> str:
        return self.cache.key("render_ref", scene=item.digest, camera=cam.to_dict(), code=self.versions.renderer,
                              **key_inputs("render_ref", self.config.protocol))

    def metrics_key(self, ref_key: str, mask: str, photo: str | None = None) -> str:
        """A view with a photo keys on its sha256 too (its entry holds the ``gt_`` metrics)."""
        extra = {"photo": photo} if photo else {}  # keys of views without a photo are unchanged
        return self.cache.key("metrics", ref=ref_key, mask=mask, code=self.versions.metrics,
                              **key_inputs("metrics", self.config.protocol), **extra)

    def gt_key(self, ref_key: str, photo: str) -> str:
        """The unpruned render of a view against its photo (and the photo's PNG at the render size)."""
        return self.cache.key("gt", ref=ref_key, photo=photo, code=self.versions.metrics,
                              **key_inputs("gt", self.config.protocol))

    def measured_names(self, photo) -> tuple[str, ...]:
        p = self.config.protocol
        return tuple(p.metrics) + (gt_names(p.metrics) if photo else ())

    def _masks(self, i: int, item: SceneItem, prunes) -> dict[str, dict[str, list[str]]]:
        """Per protocol: mask digest -> the methods and ratios measured under it that keep those
        splats (pruned on the protocol's training set)."""
        out: dict[str, dict[str, list[str]]] = {}
        for proto in item.held:
            kept_by, ts = out.setdefault(proto, {}), item.train_set(proto)
            for mv in variants_for(item, self.config.methods, proto):
                for r in mv.ratios:
                    if (rec := prunes.get((i, mv.key, ts, r))) is not None:
                        kept_by.setdefault(rec["mask"], []).append(f"{mv.key} ratio {r:g}")
        return out

    def _view_stage(self, items, prunes):
        """Reference renders first (one task per view), then the pruned sets: one task per view, so
        the view's reference features and projection are computed once for all of them, biggest
        scenes first so the workers finish together. Only when there are fewer views than
        :data:`BALANCE` tasks per worker are views split, into chunks of at least :data:`MIN_CHUNK`
        pruned sets (each chunk computes its view's reference features and projection again). A view
        with a photo also measures its unpruned render against the photo (its first task, or a task
        of its own when every pruned set is measured)."""
        refs, chunks = [], []
        views: dict[str, str] = {}  # ref key -> "scene[/frame] view NAME" (error messages)
        users: dict[str, str] = {}  # metrics key -> the methods and ratios that keep those splats
        for i, item in enumerate(items):
            masks = self._masks(i, item, prunes)
            for proto, v, cam in item.views():
                view_refs, view_chunks = self._view_work(item, proto, v, cam, masks.get(proto, {}), views, users)
                refs += view_refs
                chunks += view_chunks
        chunks = self._split_views(chunks)
        if self.executor.parallel:  # longest first; in-process order keeps a view's chunks together
            refs.sort(key=lambda t: -t.n_splats)
            chunks.sort(key=lambda ct: -ct[0])
        # one call: an executor that pipelines (Ray) starts a view's pruned sets once its reference is
        # rendered; the local one runs the two stages one after the other
        done = self._stages(Stage("render_ref", run_view, refs, on_device=_renders),
                            Stage("render+metrics", run_view, [t for _, t in chunks], weight=lambda t: len(t.masks),
                                  on_device=_renders))
        for res in done[0] + done[1]:
            for key, err in res["errors"]:
                what = views.get(res["ref_key"], res["ref_key"][:12])
                self.errors.append(f"render {what}" + ("" if key is None else f" pruned by {users.get(key) or '?'} "
                                                       f"[{key[:12]}]") + f": {err}")

    def _view_work(self, item: SceneItem, proto: str, v: int, cam, kept_by: dict, views: dict, users: dict):
        """What is still to compute of one held-out view (its label into ``views``): ([its reference
        task] or [], [(cost, jobs, task, gt key) of its pruned sets] or [])."""
        ref_key = self.ref_key(item, cam)
        views[ref_key] = f"{_where(item)} {proto} view {cam.name or f'view{v:02d}'}"
        photo = item.photo(proto, cam.name)
        # the first view of the primary protocol and of one with photos keep their renders as images
        first = v == 0 and (proto == self.primary or photo is not None)
        jobs = self._view_jobs(ref_key, kept_by, photo, first, users)
        gt_key = self._gt_to_measure(ref_key, photo, v)
        task = functools.partial(self._view_task, ref_key, item, cam, photo, views[ref_key])
        ref_png = not self.cache.has("images", ref_key, "png")  # contact sheets and figures
        have_ref = self.cache.get_json("render_ref", ref_key,
                                       check=render_ref_record_check(cam.width, cam.height)) is not None
        refs = [task([], render_ref=not have_ref, ref_png=ref_png)] if not have_ref or ref_png else []
        cost = max(len(jobs) * (1.0 + item.n_splats / 5e5) * (1.6 if photo else 1.0), 1.0)  # LPIPS pass + render (N)
        return refs, [(cost, jobs, task, gt_key)] if jobs or gt_key else []

    def _view_jobs(self, ref_key: str, kept_by: dict, photo, first: bool, users: dict) -> list[MaskJob]:
        """The pruned sets of a view still to measure (or whose image the figures still need)."""
        names = self.measured_names(photo)
        jobs = []
        for mask, kept in kept_by.items():
            mkey = self.metrics_key(ref_key, mask, photo[1] if photo else None)
            users[mkey] = ", ".join(kept)
            measured = self.cache.get_json("metrics", mkey, check=metrics_check(names)) is not None
            if not measured or (first and not self.cache.has("images", mkey, "png")):
                jobs.append(MaskJob(mkey, mask, first))
        return jobs

    def _gt_to_measure(self, ref_key: str, photo, v: int) -> str | None:
        """The ``gt`` key of a view with a photo whose unpruned render is still to measure against it
        (or, for the first view, whose photo the figures still need); else None."""
        if not photo:
            return None
        gt_key = self.gt_key(ref_key, photo[1])
        measured = self.cache.get_json("gt", gt_key, check=gt_check(gt_names(self.config.protocol.metrics))) is not None
        return None if measured and (v or self.cache.has("images", gt_key, "png")) else gt_key

    def _view_task(self, ref_key: str, item: SceneItem, cam, photo, label: str, jobs: list, render_ref=False,
                   ref_png=False, gt=None) -> ViewTask:
        p = self.config.protocol
        return ViewTask(self.cache.location, ref_key, item.path, item.spec.lod, item.digest, item.n_splats,
                        cam.to_dict(), p.renderer, p.device, p.background, p.metrics, jobs, render_ref=render_ref,
                        ref_png=ref_png, toolkit=self.toolkit, label=label, photo=photo[0] if photo else None,
                        gt=gt_names(p.metrics) if photo else (), gt_key=gt)

    def _split_views(self, chunks: list) -> list[tuple[float, ViewTask]]:
        """``(cost, task)`` per view, or per chunk of a view when there are too few views to fill the
        workers (:func:`view_parts`); the view's ``gt`` measurement goes with its first chunk."""
        # on a GPU run the views go to the device workers only: fill those
        slots = BALANCE * (getattr(self.executor, "device_workers", 0) or self.workers) if self.executor.parallel else 1
        n_views = len(chunks)
        return [(cost * max(len(part), 1) / max(len(jobs), 1), task(part, gt=gt if c == 0 else None))
                for cost, jobs, task, gt in chunks
                for c, part in enumerate(view_parts(jobs, n_views, slots))]

    # ------------------------------------------------------------------ aggregate
    def _rows(self, items, scores, prunes, skips):
        """Tidy rows and the figures' images (:func:`harness.run.rows.tidy_rows`)."""
        from harness.run.rows import tidy_rows

        return tidy_rows(self, items, scores, prunes, skips)
