"""Reader fuzzer: mutated real scene files through ``harness info`` (in-process CLI entry).

Seeds are real files: ``grape_small.ply`` (shared data), ``luigi.ply`` (fetched) cut to its first
2,000 rows by rewriting the vertex count, ASCII and big-endian re-encodings of grape's first rows,
the first 1,000 records of ``bonsai-7k-mini.splat`` (fetched), and the smallest playbot SOG level
(``6_0/meta.json`` and its images). Mutations (:mod:`tests.stress.fuzz`): header fields (counts,
format, property types and names, deleted/duplicated/junk lines), truncation, byte flips, appended
bytes, NaN/inf values, zero quaternions, SOG JSON keys and values, corrupted images.

Every case must load (exit 0) or fail with the clean error (exit 2, one ``harness: ...`` line, no
traceback). Cases run in spawned worker processes under a 6 GiB address-space limit, so a header
that makes a reader allocate absurd memory shows up as a failure instead of swapping the machine.
CI: 1,000 binary-file cases; ``HARNESS_STRESS=full``: 10,000 binary-file cases, 1,000 ascii-PLY cases
and 3,000 SOG cases. A case that runs longer than 20 s is stopped (SIGALRM) and counted as a failure.
"""

from __future__ import annotations

import json
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path

import numpy as np
import pytest

from harness.core.paths import data_dir
from harness.io import datasets
from tests.stress.budget import FULL, n
from tests.stress.fuzz import run_cases

pytestmark = [pytest.mark.stress, pytest.mark.data]


def _ply_subset(src: Path, dst: Path, rows: int, fmt: str | None = None) -> Path:
    from plyfile import PlyData

    ply = PlyData.read(str(src))
    v = ply["vertex"].data[:rows]
    from plyfile import PlyElement

    out = PlyData([PlyElement.describe(v, "vertex")], text=fmt == "ascii",
                  byte_order=">" if fmt == "big" else "<")
    out.write(str(dst))
    return dst


@pytest.fixture(scope="module")
def seeds(tmp_path_factory) -> list[dict]:
    tmp = tmp_path_factory.mktemp("fuzz_seeds")
    out = []
    grape = datasets.scene_path("grape-small")
    if grape.is_file():
        out.append({"kind": "ply", "name": "grape_small.ply", "path": str(grape)})
        out.append({"kind": "ply", "name": "grape-ascii", "path": str(_ply_subset(grape, tmp / "a.ply", 60, "ascii"))})
        out.append({"kind": "ply", "name": "grape-big-endian",
                    "path": str(_ply_subset(grape, tmp / "b.ply", 300, "big"))})
    luigi = data_dir() / "luigi.ply"
    if luigi.is_file():
        out.append({"kind": "ply", "name": "luigi-2000", "path": str(_ply_subset(luigi, tmp / "l.ply", 2000))})
    bonsai = data_dir() / "bonsai-7k-mini.splat"
    if bonsai.is_file():
        with open(bonsai, "rb") as f:
            (tmp / "s.splat").write_bytes(f.read(32 * 1000))
        out.append({"kind": "splat", "name": "bonsai-mini-1000", "path": str(tmp / "s.splat")})
    sog = datasets.scene_path("playbot") / "6_0"
    if (sog / "meta.json").is_file():
        out.append({"kind": "sog", "name": "playbot-6_0", "dir": str(sog), "meta": (sog / "meta.json").read_text()})
    if len(out) < 3:
        pytest.skip("reader fuzzer needs the shared data folder and fetched scenes (harness fetch)")
    return out


def test_seed_files_load_unmutated(seeds):
    from harness.io.scenes import read_scene

    for s in seeds:
        path = Path(s["dir"]) / "meta.json" if s["kind"] == "sog" else s["path"]
        assert len(read_scene(path).scene) > 0, s["name"]


def _fuzz(seeds, stress_counts, tmp_path, family: str, total: int) -> None:
    workers = 2 if FULL else 1
    chunk = 500 if FULL else total
    with ProcessPoolExecutor(workers, mp_context=get_context("spawn")) as pool:
        futs = [pool.submit(run_cases, seeds, start, min(chunk, total - start), str(tmp_path))
                for start in range(0, total, chunk)]
        results = [f.result() for f in futs]
    counts = {k: sum(r["counts"][k] for r in results) for k in ("loaded", "clean_error", "failure")}
    failures = [f for r in results for f in r["failures"]]
    stress_counts.add(family, **counts)
    stress_counts.note(family, "slow_cases_over_10s", sum(len(r["slow"]) for r in results))
    assert sum(counts.values()) == total
    assert not failures, (f"{counts['failure']} of {total} cases neither loaded nor failed cleanly; first: "
                          + json.dumps(failures[:5], indent=1))
    assert counts["clean_error"] > total // 4 and counts["loaded"] > 0  # the mutations do bite


def test_reader_fuzzer(seeds, stress_counts, tmp_path):
    """Binary .ply (little and big endian) and .splat seeds."""
    files = [s for s in seeds if s["kind"] != "sog" and s["name"] != "grape-ascii"]
    _fuzz(files, stress_counts, tmp_path, "readers", n(1000, 10_000))


def test_reader_fuzzer_ascii_ply(seeds, stress_counts, tmp_path):
    """ASCII .ply seed (grape's first rows re-encoded)."""
    files = [s for s in seeds if s["name"] == "grape-ascii"]
    if not files:
        pytest.skip("grape_small.ply missing from the shared data folder")
    _fuzz(files, stress_counts, tmp_path, "readers_ascii", n(100, 1_000))


def test_reader_fuzzer_sog(seeds, stress_counts, tmp_path):
    """SOG: mutated meta.json keys and values, corrupted images (smallest playbot level)."""
    sog = [s for s in seeds if s["kind"] == "sog"]
    if not sog:
        pytest.skip("playbot SOG missing from the shared data folder")
    _fuzz(sog, stress_counts, tmp_path, "readers_sog", n(100, 3_000))


def test_mutations_are_deterministic(seeds):
    from tests.stress.fuzz import mutate_binary

    s = next(x for x in seeds if x["kind"] == "ply")
    data = Path(s["path"]).read_bytes()
    a = mutate_binary("ply", data, np.random.default_rng(7))
    b = mutate_binary("ply", data, np.random.default_rng(7))
    assert a == b
