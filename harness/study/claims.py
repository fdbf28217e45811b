"""The ``claims`` table: one row per claim of the paper, tested as the paper states it, with a verdict.

Each claim is a band for a measured quantity Δ — a paired per-view difference between two cells of
the run (the same scene, views and protocol), or a level (a mean SSIM), or a benchmark's overhead —
and a *unit*: the paper states it per scene ("every row", "on breakfast and cinema") or as an
average over its scenes (Table 3, the sensitivity and runtime paragraphs).

**Per scene**, Δ's 95 % interval (:func:`harness.report.stats.mean_ci`: Student t over the n paired
views) is compared with the band: the scene *holds* when the interval lies inside the band, *fails*
when it lies entirely outside it, and is *unclear* when it straddles a bound. A claim made of
several comparisons per scene (the full method against each of three ablations) holds on a scene
when all of them hold and fails when any fails.

**Pooled** (over scenes): the mean of the per-scene means, with the t interval over the k scene
means — scenes, not views, are what a claim about "scenes" generalises over (pooling every view of
every scene would treat them as one population). One scene: its own interval.

**Verdicts** (fixed before the default study with the faithful ablation was run; README "claims"):

* per-scene claims: **holds** when every scene holds; **fails** when every scene fails; **mixed**
  when at least one holds and one fails (the per-scene split is in the row); **inconclusive**
  otherwise (some intervals straddle a bound and none contradicts another);
* average claims: **holds** / **fails** / **inconclusive** by the pooled interval against the band;
* the heterogeneity claim holds when at least one scene's descriptor gain is above 0 and one below
  (both intervals), fails when every scene's interval is on the same side, else inconclusive;
* **not testable here**: the run lacks a cell the claim needs (named), or the claim cannot be tested
  as stated (the paper gives no values for three of its four presets).

Bands (the paper's number it is read from in brackets):

* T1 competitive at 10 % and 20 % (L327): BetaDesc − the best camera-aware method (higher mean at
  that scene and ratio) > −5.15 dB — the largest deficit the paper's own Table 1 calls competitive
  (cinema, mid: 26.34 vs 31.49);
* T1 better at 30 % on large scenes (L327: +1.05 breakfast, +1.80 cinema): > 0 on the scenes of
  ≥ :data:`LARGE_SPLATS` splats (per scene);
* T2 full method best in every row (L387): full − each ablation > 0 at 20 %; descriptors help
  (full − no-descriptors > 0), Beta helps with and without descriptors (> 0);
* T3 descriptors help (L461-463: +1.63/+0.89/+1.02 dB): with − without descriptors > 0 at keep
  0.7, 0.5, 0.3 (one row each), average; the gap is modest ("within 1.6 dB PSNR across all tests",
  L465): |with − without| ≤ 1.6 dB at all three keeps, average;
* degradation monotonic (L461): PSNR(keep 0.7) > PSNR(0.5) > PSNR(0.3), per scene; SSIM > 0.87 at
  keep 0.3 (L461), average;
* heterogeneity (L465: +4.04 … −12.4 dB at 70 % pruning): the descriptor gain at keep 0.3 has both
  signs across scenes;
* presets (L468: spread 0.18 dB / 0.002 SSIM): not testable as stated (see above); our presets'
  Δ against the baseline preset are shown;
* voxel 0.10/0.20/0.30 × diagonal flat (L470: 36.24/36.34/36.14): Δ of 0.20 and 0.30 against 0.10
  within ±0.20 dB (the paper's own spread), average; the same for 1/2/3 % (the project's earlier
  reading of that sentence) where the run has it;
* runtime overhead ≈ 8 % (L474: 7.29 vs 6.78 s, single thread): the benchmark's overhead of the full
  method over the no-descriptor variant ≤ 16 % (twice the paper's figure), average over the
  benchmark's scenes of the run (``harness bench methods --overhead``, ``results/bench/overhead.json``).
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd

from harness.core import ratios
from harness.report import catalog, cells, stats
from harness.report.tabledata import Missing, Table
from harness.study.verdicts import (
    INF,
    MARK,
    Estimate,
    Result,
    Run,
    comparisons,
    estimate,
    need,
    outcome,
)
from methods.registry import GROUPS

#: "large scenes" of the Table 1 high-ratio claim: at least this many splats (the paper's breakfast
#: and cinema are room-scale captures; of the public scenes only bonsai-7k qualifies)
LARGE_SPLATS = 1_000_000


# --------------------------------------------------------------------------- claims
def camera_aware(run: Run) -> list[str]:
    """The run's methods of the registry's camera-aware group."""
    return [m for grp, m in catalog.comparison_methods(run.ok["method"]) if grp == GROUPS["camera-aware"]]


def _best_camera_aware(run: Run, scene: str, ratio: float):
    """(method, ratio) of the camera-aware method with the higher mean PSNR at this scene and ratio."""
    best = None
    for m in camera_aware(run):
        g = run.cell(scene, m, ratio)
        if g is not None:
            mean = stats.summary(g["psnr"], g["near"], "psnr")["mean"]
            mean = INF if not np.isfinite(mean) and g["near"].all() else mean  # lossless on every view
            if not np.isnan(mean) and (best is None or mean > best[0]):
                best = (mean, m)
    return (best[1], ratio) if best else None


def claim_t1_competitive(run: Run, ratio: float) -> Result:
    full = catalog.proposed_method()
    res = Result(f"t1-competitive-{ratios.percent(ratio)}", "Table 1: competitive with camera-aware pruning (L327)",
                 "deficit to the best camera-aware method 0.12–5.15 dB at low/mid (its 4 scenes)",
                 f"prune {ratios.percent(ratio)}", "scene", (-5.15, INF))
    if not camera_aware(run):
        res.why = "no camera-aware method was measured"
        return res
    need(run, res, [(full, ratio)])
    if res.why:
        return res
    _best_note(run, res, ratio)
    return comparisons(run, res, [("BetaDesc − best camera-aware", lambda s: (full, ratio),
                                    lambda s: _best_camera_aware(run, s, ratio))]).decide()


def _best_note(run: Run, res: Result, ratio: float) -> None:
    best = {run.labels[s]: _best_camera_aware(run, s, ratio) for s in run.labels}
    res.note = "best camera-aware per scene: " + ", ".join(
        f"{lab} {catalog.method_label(b[0])}" for lab, b in best.items() if b)


def claim_t1_large(run: Run, ratio: float = 0.3) -> Result:
    full = catalog.proposed_method()
    res = Result("t1-large-high", "Table 1: better than camera-aware at high ratios on large scenes (L327)",
                 "+1.05 (breakfast), +1.80 dB (cinema) over the best camera-aware", f"prune {ratios.percent(ratio)}",
                 "scene", (0.0, INF))
    large = [s for s in run.labels if run.splats(s) >= LARGE_SPLATS]
    if not large:
        res.why = f"no scene of ≥ {LARGE_SPLATS:,} splats (the paper's large, room-scale scenes)"
        return res
    _best_note(run, res, ratio)
    comparisons(run, res, [("BetaDesc − best camera-aware", lambda s: (full, ratio),
                             lambda s: _best_camera_aware(run, s, ratio))])
    res.per_scene = {s: v for s, v in res.per_scene.items() if s in large}
    res.note += f"; large = ≥ {LARGE_SPLATS:,} splats: {', '.join(run.labels[s] for s in large)}"
    return res.decide()


def claim_t2(run: Run, key: str, claim: str, paper: str, pairs: list[tuple[str, str]], ratio: float = 0.2) -> Result:
    res = Result(key, claim, paper, f"prune {ratios.percent(ratio)}", "scene", (0.0, INF))
    need(run, res, [(m, ratio) for pair in pairs for m in pair])
    if res.why:
        return res
    specs = [(f"{catalog.method_label(a)} − {catalog.method_label(b)}", lambda s, a=a: (a, ratio),
              lambda s, b=b: (b, ratio)) for a, b in pairs]
    return comparisons(run, res, specs).decide()


def _descriptor_gain(run: Run, res: Result, keeps) -> Result:
    """Comparisons "with − without descriptors" at each of ``keeps`` (both with the Beta score)."""
    pair = catalog.descriptor_pair()
    if pair is None:
        res.why = "no registered pair with and without descriptors"
        return res
    without, full = pair
    rs = [ratios.from_keep(k) for k in keeps]
    need(run, res, [(m, r) for r in rs for m in (full, without)])
    if res.why:
        return res
    label = "with − without descriptors"
    specs = [
        ((label if len(rs) == 1 else f"{label}, keep {k:g}"), lambda s, r=r: (full, r), lambda s, r=r: (without, r))
        for k, r in zip(keeps, rs)
    ]
    return comparisons(run, res, specs).decide()


def claim_t3(run: Run, keep: float) -> Result:
    res = Result(f"t3-keep-{keep:g}", "Table 3: descriptors help (L461-463)",
                 {0.7: "+1.63", 0.5: "+0.89", 0.3: "+1.02"}.get(keep, "") + " dB (14-scene mean)",
                 f"keep {keep:g}", "average", (0.0, INF))
    return _descriptor_gain(run, res, [keep])


def claim_t3_gap(run: Run) -> Result:
    res = Result("t3-gap", "Table 3: the descriptor gap stays modest, ≲ 1.6 dB either way (L463, L465)",
                 "+1.63 / +0.89 / +1.02 dB; \"within 1.6 dB PSNR across all tests\"", "keep 0.7 / 0.5 / 0.3",
                 "average", (-1.6, 1.6))
    return _descriptor_gain(run, res, list(cells.KEEPS))


def claim_monotonic(run: Run) -> Result:
    full = catalog.proposed_method()
    a, b, c = (ratios.from_keep(k) for k in (0.7, 0.5, 0.3))
    res = Result("t3-monotonic", "Table 3: quality degrades monotonically with pruning (L461)",
                 "37.38 > 33.68 > 29.07 dB (keep 0.7 / 0.5 / 0.3)", "keep 0.7 → 0.5 → 0.3", "scene", (0.0, INF))
    need(run, res, [(full, a), (full, b), (full, c)])
    if res.why:
        return res
    return comparisons(run, res, [("keep 0.7 − 0.5", lambda s: (full, a), lambda s: (full, b)),
                                   ("keep 0.5 − 0.3", lambda s: (full, b), lambda s: (full, c))]).decide()


def claim_ssim_floor(run: Run, keep: float = 0.3) -> Result:
    full = catalog.proposed_method()
    r = ratios.from_keep(keep)
    res = Result("t3-ssim", "Table 3: SSIM stays above 0.87 at 70 % removal (L461)", "0.882 (14-scene mean)",
                 f"keep {keep:g}", "average", (0.87, INF), digits=3)
    need(run, res, [(full, r)])
    if res.why or "ssim" not in run.ok:
        res.why = res.why or "the run measured no SSIM"
        return res
    for s in run.labels:
        e = run.level(s, full, r, "ssim")
        if e is not None:
            res.per_scene[s] = [("mean SSIM", e)]
    return res.decide()


def claim_heterogeneity(run: Run, keep: float = 0.3) -> Result:
    res = _descriptor_gain(run, Result("", "", "", "", "split"), [keep])
    return Result("heterogeneity", "Per-scene heterogeneity: descriptors help on some scenes, hurt on others (L465)",
                  "+4.04 (solo_tango_male) … −12.4 dB (flowerdance) at 70 % pruning", f"keep {keep:g}", "split",
                  (0.0, INF), res.per_scene, why=res.why).decide()


def claim_sweep(run: Run, key: str, claim: str, paper: str, param: str, reference, values, band,
                keep: float = 0.7, untestable: str = "") -> Result:
    """Each ``param`` value's Δ against the ``reference`` value (None: the default variant), betadesc
    variants at ``keep``. ``untestable``: the numbers are shown but the claim cannot be judged (why)."""
    full = catalog.proposed_method()
    r = ratios.from_keep(keep)
    res = Result(key, claim, paper, f"keep {keep:g}", "average", band)
    ref = "default" if reference is None else run.variant_with(full, r, param, reference)
    found = {v: run.variant_with(full, r, param, v) for v in values}
    absent = [f"{param}={_fmt(v)}" for v, name in [(reference, ref), *found.items()] if name is None]
    if ref is None or all(name is None for name in found.values()):
        res.why = f"the run has no {full} variant {', '.join(absent)} at keep {keep:g}"
        return res
    ref_text = "default" if reference is None else _fmt(reference)
    specs = [(f"{param} {_fmt(v)} − {ref_text}", lambda s, n=name: (full, r, n), lambda s: (full, r, ref))
             for v, name in found.items() if name is not None]
    comparisons(run, res, specs).decide()
    why = untestable or (f"the run has no {full} variant {', '.join(absent)} at keep {keep:g}" if absent else "")
    if why:  # the measured comparisons stay in the row; the claim is not judged
        res.verdict, res.why = "not testable here", why
    return res


def _fmt(v) -> str:
    return format(v, "g") if isinstance(v, float) else str(v)


def claim_overhead(run: Run, bench: dict | None) -> Result:
    res = Result("runtime", "Runtime: descriptors add ≈ 8 % (single thread, method timing; L474)",
                 "7.29 vs 6.78 s per scene: +0.5 s, ≈ 8 %", "scoring only", "average", (-INF, 16.0), digits=1)
    if not bench:
        res.why = "no benchmark: run `harness bench methods --overhead` (results/bench/overhead.json)"
        return res
    scenes = {r["scene"]: r for r in bench.get("scenes", [])}
    for s in run.labels:
        if s in scenes:
            res.per_scene[s] = [("overhead %", estimate(scenes[s]["overhead_pct"]))]
    res.note = (f"per scene: {bench.get('repeats', '?')} timed repeats of `harness bench methods --overhead` "
                f"({bench.get('when', 'undated')}), process CPU seconds at one thread")
    if not res.per_scene:
        res.why = f"the overhead benchmark timed none of this run's scenes ({', '.join(scenes) or 'none'})"
        return res
    return res.decide()


# --------------------------------------------------------------------------- the table
PRESETS_UNTESTABLE = ("the paper names flat, opacity-heavy and structure-heavy without values; ours are our "
                      "own (methods/betadesc/evidence.py), so their spread says nothing about the paper's")


def results(df: pd.DataFrame, overhead: dict | None = None) -> list[Result]:
    """Every claim of the paper tested on ``df`` (one protocol's rows) in the order of the paper."""
    from methods.registry import ablation_grid

    run = Run.of(df)
    grid = {k: spec.name for k, spec in ablation_grid().items()}
    full, nodesc, nobeta, neither = (grid.get(k) for k in ((True, True), (False, True), (True, False), (False, False)))
    ablations = [m for m in (neither, nodesc, nobeta) if m]
    out = [claim_t1_competitive(run, 0.1), claim_t1_competitive(run, 0.2), claim_t1_large(run),
           claim_t2(run, "t2-best", "Table 2: the full method is best in every row (L387)",
                    "full − best ablation +1.84 / +5.57 / +0.01 / 0.00 dB", [(full, m) for m in ablations]),
           claim_t2(run, "t2-descriptors", "Table 2: descriptors help (L384-386)",
                    "+1.84 / +5.57 / +0.01 / 0.00 dB", [(full, nodesc)]),
           claim_t2(run, "t2-beta", "Table 2: Beta evidence helps, with descriptors (L386)",
                    "+7.19 / +16.53 / +7.71 / +3.32 dB", [(full, nobeta)]),
           claim_t2(run, "t2-beta-nodesc", "Table 2: Beta evidence helps, without descriptors (L386)",
                    "+4.32 / +8.92 / +5.39 / +3.32 dB", [(nodesc, neither)]),
           *(claim_t3(run, k) for k in cells.KEEPS), claim_t3_gap(run), claim_monotonic(run), claim_ssim_floor(run),
           claim_heterogeneity(run),
           claim_sweep(run, "presets", "Sensitivity: coefficient presets spread ≤ 0.18 dB PSNR, 0.002 SSIM (L468)",
                       "36.26–36.44 dB, SSIM 0.9721–0.9737 (5 scenes)", "preset", None,
                       ["flat", "opacity-heavy", "structure-heavy"], (-0.18, 0.18), untestable=PRESETS_UNTESTABLE),
           claim_sweep(run, "voxel-literal", "Sensitivity: voxel 0.10 / 0.20 / 0.30 × diagonal is flat (L470)",
                       "36.24 / 36.34 / 36.14 dB (spread 0.20)", "voxel", 0.1, [0.2, 0.3], (-0.2, 0.2)),
           claim_sweep(run, "voxel-percent", "Sensitivity: voxel 1 / 2 / 3 % of the diagonal is flat "
                       "(our earlier reading of L470)", "36.24 / 36.34 / 36.14 dB (spread 0.20)", "voxel", 0.01,
                       [0.02, 0.03], (-0.2, 0.2)),
           claim_overhead(run, overhead if overhead is not None else read_overhead())]
    for r in out:
        for s in list(r.per_scene):
            r.per_scene[run.labels[s]] = r.per_scene.pop(s)  # display labels from here on
    return out


def read_overhead() -> dict | None:
    """``results/bench/overhead.json`` (``harness bench methods --overhead``), or None."""
    from harness.core.paths import results_dir

    path = results_dir() / "bench" / "overhead.json"
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def _band_text(band, unit: str) -> str:
    if unit == "split":
        return "> 0 on some scenes, < 0 on others"
    lo, hi = band
    if lo == -INF:
        return f"≤ {hi:g}"
    if hi == INF:
        return f"> {lo:+g}"
    return f"in ({lo:+g}, {hi:+g}]"


def table_claims(df: pd.DataFrame, overhead: dict | None = None):
    found = results(df, overhead)
    if all(r.verdict == "not testable here" and not r.pooled for r in found):
        return Missing("no claim of the paper is testable on these results: " + "; ".join(
            f"{r.key}: {r.why}" for r in found[:3]))
    rows, tidy = [], []
    for r in found:
        pooled_text = "; ".join(f"{n}: {e.text(r.digits)}" for n, e in r.pooled.items())
        if r.pooled and r.unit != "scene":
            k = len(r.per_scene)
            pooled_text += f" ({k} scene{'s' * (k != 1)})"
        per = " · ".join(
            f"{lab} {min(comps, key=lambda c: c[1].mean if np.isfinite(c[1].mean) else INF)[1].text(r.digits)} "
            f"{MARK[r.scene_outcome(lab)]}" for lab, comps in r.per_scene.items())
        verdict = r.verdict + (f" ({r.why})" if r.why else "")
        rows.append([r.claim, r.paper, r.at, _band_text(r.band, r.unit), pooled_text or "–", per or "–", verdict])
        for lab, comps in r.per_scene.items():
            for n, e in comps:
                tidy.append(_tidy(r, n, lab, e, outcome(e, r.band)))
        for n, e in r.pooled.items():
            tidy.append(_tidy(r, n, cells.POOLED, e, outcome(e, r.band)))
        if not r.per_scene:
            tidy.append(_tidy(r, "", "", Estimate(np.nan, np.nan, np.nan, 0), ""))
    disp = pd.DataFrame(rows, columns=["claim", "paper", "at", "claimed band", "measured: pooled over scenes",
                                       "per scene (✓ holds, ✗ fails, ? unclear)", "verdict"])
    disp.index = pd.Index([r.key for r in found], name="key")
    notes = [
        stats.interval_note(t["n"] for t in tidy if t["scene"] not in (cells.POOLED, "") and t["key"] != "runtime"),
        "pooled = mean of the per-scene means, t interval over the scenes (n = scenes); per scene: the "
        "comparison with the lowest mean where a claim has several",
        "verdicts (harness/report/claims.py): per-scene claims hold if every scene holds, fail if every "
        "scene fails, are mixed on a split, else inconclusive; average claims by the pooled interval; "
        "a scene holds when its interval lies inside the claimed band, fails when it lies outside",
        *[f"{r.key}: {r.note}" for r in found if r.note],
    ]
    return Table(disp, notes, pd.DataFrame(tidy, columns=TIDY))


TIDY = ["key", "claim", "paper", "at", "unit", "band_low", "band_high", "comparison", "scene", "mean", "ci_low",
        "ci_high", "n", "outcome", "verdict", "why"]


def _tidy(r: Result, comparison: str, scene: str, e: Estimate, oc: str) -> dict:
    return {"key": r.key, "claim": r.claim, "paper": r.paper, "at": r.at, "unit": r.unit, "band_low": r.band[0],
            "band_high": r.band[1], "comparison": comparison, "scene": scene, "mean": e.mean, "ci_low": e.lo,
            "ci_high": e.hi, "n": e.n, "outcome": oc, "verdict": r.verdict, "why": r.why}
