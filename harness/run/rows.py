"""The aggregate stage of a run: tidy rows from the stage cache, one per (scene, frame, method,
variant, ratio, held-out view), and the images the figures show.

A view measures the masks of its protocol's training set; a view with a photo carries the ``gt_``
metrics of the pruned render and (``unpruned_gt_*``) of the unpruned one. A failed (scores, ratio)
is one ``error`` row; a view whose metrics entry is missing an ``error`` row of its own. Images:
the first view of the primary protocol, and of a protocol whose views have photos (``real``),
with its photo.
"""

from __future__ import annotations

from harness.core import ratios
from harness.metrics.registry import gt_names
from harness.run.cache import canonical_json
from harness.run.plan import variants_for
from harness.run.verify import gt_check, metrics_check, render_ref_record_check


def tidy_rows(runner, items, scores, prunes, skips) -> tuple[list[dict], dict]:
    """``(rows, images)`` of a run (module docstring); ``runner``: the :class:`harness.run.runner.Runner`
    whose cache and keys the stages used."""
    base = {"run": runner.config.name, "renderer": runner.config.protocol.renderer}
    rows, images, failed = _skip_rows(runner.config, skips, base), {}, set()
    for i, item in enumerate(items):
        views, ref_recs, unpruned = _views(runner, item)
        images.update(_input_images(runner, item, views))
        for mv in variants_for(item, runner.config.methods):
            ident = {**base, "scene": item.spec.name, "label": item.spec.label, "kind": item.spec.kind,
                     "frame": item.frame, "method": mv.method, "variant": mv.variant,
                     "params": canonical_json(mv.params.to_dict()), "splats_in": item.n_splats}
            for ts in item.train_sets():
                if (i, mv.key, ts) not in scores:
                    continue  # recorded as a skip
                skey, srec = scores[(i, mv.key, ts)]
                for r in mv.ratios:
                    row0 = {**ident, "ratio": r, "keep": ratios.to_keep(r)}
                    prec = prunes.get((i, mv.key, ts, r))
                    if "error" in srec or prec is None:  # one row per failed (scores, ratio)
                        if (skey, r) not in failed:
                            failed.add((skey, r))
                            rows.append({**row0, "status": "error", "reason": srec.get(
                                "error", "pruning failed (see run.json errors)")})
                        continue
                    row0.update(splats_out=prec["splats_out"], bytes=item.ply_bytes(prec["splats_out"]),
                                tau=prec["tau"], tau_quantile=prec["tau_quantile"],
                                score_s=srec["seconds"], prune_s=prec["seconds"])
                    for view in (v for v in views if item.train_set(v[0]) == ts and mv.measures(v[0])):
                        rows.append(_view_row(runner, item, mv, r, row0, prec["mask"], view, ref_recs, unpruned,
                                              images))
    return rows, images


def _skip_rows(config, skips, base: dict) -> list[dict]:
    rows = []
    for sk in skips:
        spec = next((s for s in config.scenes if s.name == sk.scene), None)
        rows.append({**base, "scene": sk.scene, "label": spec.label if spec else sk.scene,
                     "kind": spec.kind if spec else "", "frame": sk.frame, "method": sk.method,
                     "variant": sk.variant, "status": sk.status, "reason": sk.reason})
    return rows


def _views(runner, item):
    """The item's views ``(protocol, index, camera, reference key, photo)``, their reference render
    records, and per view with a photo the unpruned render's ``unpruned_gt_*`` values."""
    views = [(proto, v, cam, runner.ref_key(item, cam), item.photo(proto, cam.name))
             for proto, v, cam in item.views()]
    ref_recs = {rk: runner.cache.load_json("render_ref", rk, check=render_ref_record_check(c.width, c.height)) or {}
                for _, _, c, rk, _ in views}
    gt_ok = gt_check(gt_names(runner.config.protocol.metrics))
    unpruned = {rk: {f"unpruned_{k}": v for k, v in (runner.cache.load_json(
        "gt", runner.gt_key(rk, ph[1]), check=gt_ok) or {}).items() if k != "seconds"}
        for _, _, _, rk, ph in views if ph}
    return views, ref_recs, unpruned


def _figure_frame(runner, item, proto: str, v: int, photo) -> str | None:
    """The frame name under which a view's images are kept for the figures (None: not kept)."""
    if v != 0 or not (proto == runner.primary or photo):
        return None
    return item.frame if proto == runner.primary else "/".join(x for x in (item.frame, proto) if x)


def _input_images(runner, item, views) -> dict:
    out = {}
    for proto, v, _, rk, ph in views:
        frame = _figure_frame(runner, item, proto, v, ph)
        if frame is not None:
            out[(item.spec.name, frame, "input", "", 0.0)] = runner.cache.path("images", rk, "png")
            if ph:
                out[(item.spec.name, frame, "photo", "", 0.0)] = \
                    runner.cache.path("images", runner.gt_key(rk, ph[1]), "png")
    return out


def _view_row(runner, item, mv, r: float, row0: dict, mask: str, view, ref_recs, unpruned, images) -> dict:
    """The row of one pruned set (``mask``) on one view, and its image for the figures."""
    proto, v, cam, rk, ph = view
    mkey = runner.metrics_key(rk, mask, ph[1] if ph else None)
    names = runner.measured_names(ph)
    m = runner.cache.load_json("metrics", mkey, check=metrics_check(names))
    row = {**row0, "protocol": proto, "view": cam.name or f"view{v:02d}", "width": cam.width, "height": cam.height,
           "render_ref_s": ref_recs[rk].get("seconds")}
    if m is None:
        row.update(status="error", reason="render or metrics failed (see run.json errors)")
        return row
    row.update(status="ok", render_s=m["render_s"], metrics_s=m["metrics_s"],
               **{k: m[k] for k in (*names, "occupancy") if k in m}, **unpruned.get(rk, {}))
    frame = _figure_frame(runner, item, proto, v, ph)
    if frame is not None:
        images[(item.spec.name, frame, mv.method, mv.variant, r)] = runner.cache.path("images", mkey, "png")
    return row
