"""Every verdict of a committed claims table follows from the committed per-view measurements by the
documented rules (docs/claims.md), recomputed here independently of harness/report: the paired
differences from views.csv.gz with the 100 dB cap, Holm's step-down written out again, the
random-effects interval from statsmodels, the type rules from the document.

A study folder qualifies when it holds ``views.csv.gz`` and ``claims*.csv`` (``results/claims-ci``:
a run of ``ctc_configs/study/claims_ci.yaml``; ``results/default`` once the default study is committed with
its per-view file). The runtime rows come from the benchmark, not the views: their per-scene numbers
are taken as recorded and their verdicts recomputed."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy import stats

ROOT = Path(__file__).resolve().parent.parent / "results"
FOLDERS = [p for p in (ROOT / "claims-ci", ROOT / "default") if (p / "views.csv.gz").is_file()]
ALPHA, MIN_SCENES, CAP = 0.025, 4, 100.0
POOLED = "pooled over scenes"


def _tables(folder: Path) -> list[Path]:
    return sorted(p for p in folder.glob("claims*.csv") if p.is_file())


def _cases():
    out = [(f, t) for f in FOLDERS for t in _tables(f)]
    return out or [pytest.param(None, None, marks=pytest.mark.skip(
        reason="no committed study with views.csv.gz and claims*.csv under results/"))]


@pytest.fixture(scope="module")
def views():
    cache = {}

    def get(folder: Path) -> pd.DataFrame:
        if folder not in cache:
            cache[folder] = pd.read_csv(folder / "views.csv.gz", dtype={"variant": str, "view": str, "frame": str})
        return cache[folder]
    return get


def _cell(v: pd.DataFrame, protocol: str, scene: str, cell: str, metric: str) -> pd.Series:
    method, rest = cell.split(":", 1)
    variant, ratio = rest.rsplit("@", 1)
    rows = v[(v["protocol"] == protocol) & (v["scene"] == scene) & (v["method"] == method)
             & (v["variant"] == variant) & np.isclose(v["ratio"], float(ratio))]
    s = pd.Series(rows[metric].to_numpy(float), index=list(zip(rows["frame"].fillna(""), rows["view"])))
    return s.clip(upper=CAP) if metric == "psnr" else s


def _estimate(values) -> tuple[float, float, int]:
    x = np.asarray(values, float)
    return float(x.mean()), float(x.std(ddof=1) / math.sqrt(x.size)), x.size - 1


def _recompute(v, protocol, row) -> tuple[float, float, int]:
    metric = "ssim" if row["comparison"] == "mean SSIM" else "psnr"
    a = _cell(v, protocol, row["scene"], row["a"], metric)
    if not isinstance(row["b"], str) or not row["b"]:
        return _estimate(a.dropna())
    b = _cell(v, protocol, row["scene"], row["b"], metric)
    both = a.index.intersection(b.index, sort=False)
    x, y = a[both].to_numpy(), b[both].to_numpy()
    keep = np.isfinite(x) & np.isfinite(y)
    if metric == "psnr":
        keep &= ~((x >= CAP) & (y >= CAP))  # identical on both sides: left out
    return _estimate((x - y)[keep])


def _p_in(m, se, df, lo, hi):
    def up(t):
        return 1.0 if math.isnan(t) else float(stats.t.sf(t, df))
    with np.errstate(divide="ignore", invalid="ignore"):
        p_lo = up(float(np.float64(m - lo) / se)) if lo > -math.inf else 0.0
        p_hi = up(float(np.float64(hi - m) / se)) if hi < math.inf else 0.0
    return max(p_lo, p_hi)


def _p_out(m, se, df, lo, hi):
    with np.errstate(divide="ignore", invalid="ignore"):
        below = float(stats.t.sf(float(np.float64(lo - m) / se), df)) if lo > -math.inf else 1.0
        above = float(stats.t.sf(float(np.float64(m - hi) / se), df)) if hi < math.inf else 1.0
    return min(1.0 if math.isnan(below) else below, 1.0 if math.isnan(above) else above)


def _holm(p) -> list[bool]:
    m, out = len(p), [False] * len(p)
    for j, i in enumerate(sorted(range(m), key=lambda i: p[i])):
        if p[i] > ALPHA / (m - j):
            break
        out[i] = True
    return out


def _family(ests, band) -> str:
    held = _holm([_p_in(*e, *band) for e in ests])
    failed = _holm([_p_out(*e, *band) for e in ests])
    return "fails" if any(failed) else "holds" if all(held) else "inconclusive"


def _pool(ests) -> tuple[float, float, int]:
    from statsmodels.stats.meta_analysis import combine_effects

    y = [e[0] for e in ests]
    var = [max(e[1] ** 2, 1e-12) for e in ests]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        f = combine_effects(np.asarray(y), np.asarray(var), method_re="dl", use_t=True).summary_frame()
    return float(f.loc["random effect", "eff"]), max(f.loc["random effect wls", "sd_eff"],
                                                      f.loc["random effect", "sd_eff"]), len(y) - 1


def _verdict(rows: pd.DataFrame, ests: dict) -> tuple[str, dict]:
    """The documented rule for one claim under one reading from its per-scene estimates."""
    first = rows.iloc[0]
    kind, unit = first["type"], first["unit"]
    band = (first["band_low"], first["band_high"])
    scenes = list(dict.fromkeys(s for s, _ in ests))
    comparisons = list(dict.fromkeys(c for _, c in ests))

    def by_unit(u, b):
        if u == "universal":
            return _family(list(ests.values()), b)
        pooled = [_pool([ests[(s, c)] for s in scenes]) for c in comparisons]
        return _family(pooled, b)

    if kind == "existence":
        e = [ests[(s, comparisons[0])] for s in scenes]
        rej = _holm([_p_in(*x, 0.0, math.inf) for x in e] + [_p_in(*x, -math.inf, 0.0) for x in e])
        up, down = rej[:len(e)], rej[len(e):]
        verdict = "holds" if any(up) and any(down) else "fails" if all(up) or all(down) else "inconclusive"
        return ("underpowered" if len(scenes) < MIN_SCENES else verdict), {}
    if kind == "effect size":
        parts = {"direction": by_unit(unit, (0.0, math.inf)), "size": by_unit(unit, (first["size_low"], math.inf))}
        if len(scenes) < MIN_SCENES:
            return "underpowered", {k: "underpowered" for k in parts}
        v = parts.values()
        return ("fails" if "fails" in v else "holds" if all(x == "holds" for x in v) else "inconclusive"), parts
    verdict = by_unit("universal" if kind == "universal" else "average", band)
    return ("underpowered" if len(scenes) < MIN_SCENES else verdict), {}


def _read(table: Path) -> pd.DataFrame:
    claims = pd.read_csv(table, dtype={"b": str, "a": str, "scene": str, "why": str})
    for c in ("b", "a", "scene", "why", "verdict_direction", "verdict_size"):
        claims[c] = claims[c].fillna("")
    return claims


def check(v: pd.DataFrame, claims: pd.DataFrame) -> int:
    """Assert every verdict of ``claims`` (a claims CSV) from the per-view file ``v``; claims checked."""
    checked = 0
    for (key, reading), rows in claims.groupby(["key", "reading"], sort=False):
        protocol = rows["protocol"].iloc[0] if "protocol" in rows else "rig"
        recorded = rows["verdict_reading"].iloc[0]
        if recorded == "not testable here":
            continue
        per = rows[(rows["scene"] != "") & (rows["scene"] != POOLED)]
        ests = {}
        for _, r in per.iterrows():
            if r["a"].count(":"):  # a cell of the run: recomputed from the views
                m, se, df = _recompute(v, protocol, r)
                assert (m, df) == (pytest.approx(r["mean"], abs=1e-9), r["df"]), (key, reading, r["scene"])
                assert se == pytest.approx(r["se"], abs=1e-9, nan_ok=True), (key, reading, r["scene"])
            else:  # the runtime benchmark: as recorded
                m, se, df = r["mean"], r["se"], int(r["df"])
            ests[(r["scene"], r["comparison"])] = (m, se, df)
        if recorded == "not comparable (render size)":
            sides = v.loc[v["protocol"] == protocol, ["width", "height"]].max(axis=1)
            assert set(sides.astype(int)) != {1024}, key
            continue
        verdict, parts = _verdict(rows, ests)
        assert verdict == recorded, (key, reading, verdict, recorded)
        if parts:
            assert (parts["direction"], parts["size"]) == (rows["verdict_direction"].iloc[0],
                                                           rows["verdict_size"].iloc[0]), (key, reading)
        checked += 1
    for key, rows in claims.groupby("key", sort=False):  # the verdict over the readings
        by = rows.drop_duplicates("reading").set_index("reading")["verdict_reading"]
        testable = set(by[by != "not testable here"])
        want = "not testable here" if not testable else testable.pop() if len(testable) == 1 else \
            "depends on the reading"
        assert rows["verdict"].iloc[0] == want, key
    return checked


@pytest.mark.parametrize("folder, table", _cases(), ids=lambda x: x.name if isinstance(x, Path) else str(x))
def test_every_verdict_follows_from_the_per_view_file(views, folder, table):
    pytest.importorskip("statsmodels", reason="statsmodels (the test extra) is the independent meta-analysis")
    assert check(views(folder), _read(table)), f"{table}: no verdict to re-derive"


@pytest.mark.parametrize("folder, table", _cases()[:1], ids=lambda x: x.name if isinstance(x, Path) else str(x))
def test_a_planted_error_is_caught(views, folder, table):
    pytest.importorskip("statsmodels", reason="statsmodels (the test extra) is the independent meta-analysis")
    claims, v = _read(table), views(folder)
    judged = claims[~claims["verdict_reading"].isin(["not testable here", "not comparable (render size)"])]
    key, reading = judged[["key", "reading"]].iloc[0]
    wrong = claims.copy()
    here = (wrong["key"] == key) & (wrong["reading"] == reading)
    wrong.loc[here, "verdict_reading"] = "holds" if judged["verdict_reading"].iloc[0] != "holds" else "fails"
    with pytest.raises(AssertionError):
        check(v, wrong)
    cell = claims[claims["a"].str.contains(":") & claims["scene"].ne(POOLED) & claims["scene"].ne("")].index[0]
    moved = claims.copy()
    moved.loc[cell, "mean"] += 0.01
    with pytest.raises(AssertionError):
        check(v, moved)
