"""Same input, same bytes: a study run twice cold, on one process with two threads and on a pool of
two single-threaded workers, writes the same tables and plots and stores the same stage-cache entries
(scores, masks, renders, every metric of every view), byte for byte, measured seconds aside.

``tests/configs/determinism.yaml`` is the default study in miniature (every method entry, protocol,
table and plot of ``ctc_configs/default.yaml``, on a generated scene and capture, sized so that torch
splits per-splat and per-image work across threads); ``determinism_ci.yaml`` the part of it the fast
tier runs: the methods whose kernels are parallel or thread-sensitive (ConfSplat's torch training,
BetaDescPrune's numba kernels, the virtual rig's significance), under the rig and real protocols.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from PIL import Image

from harness.core.cameras import Camera
from harness.io.cameras import write_3dgs_cameras
from harness.io.scenes import write_scene
from harness.metrics.lpips_weights import weights_path
from tests.gl_support import require_gl
from tests.scene_factory import random_scene

REPO = Path(__file__).resolve().parent.parent
CONFIGS = REPO / "tests" / "configs"
#: on two threads torch's per-splat kernels take chunks of 20,031 splats: ends off the vector grid
N_SPLATS = 40_062
#: (workers, threads per worker) of the two runs: in-process on two threads; two single-thread workers
RUNS = ((1, 2), (2, 1))
#: table columns / long-format rows holding measured seconds (the runtime tables hold nothing else)
SECONDS = re.compile(r"^(seconds|.*\(s\)|.*_s|.*_s_std)$")


def _world(folder: Path) -> None:
    """The scene and capture the configs name: ``blob.ply`` and ``capture/`` (six cameras around it,
    photos of a fixed pattern; the ``gt_`` metrics only have to be computed, not to mean anything)."""
    scene = random_scene(N_SPLATS, sh_degree=1, seed=11)
    scene.scales_log[:] += 1.0  # splats that overlap: long front-to-back sums per pixel
    write_scene(scene, folder / "blob.ply")
    cams = [Camera.look_at((5 * math.cos(a), 1.5 * math.sin(3 * a), 5 * math.sin(a)), (0, 0, 0), fov_y_deg=45,
                           width=192, height=144, name=f"cap{i}")
            for i, a in enumerate(np.linspace(0, 2 * math.pi, 6, endpoint=False))]
    write_3dgs_cameras(cams, folder / "capture" / "cameras.json")
    (folder / "capture" / "photos").mkdir()
    y, x = np.mgrid[0:144, 0:192]
    for i, c in enumerate(cams):
        img = np.stack([(x * (i + 1)) % 256, (y * 3 + 40 * i) % 256, (x + y) % 256], -1).astype(np.uint8)
        Image.fromarray(img).save(folder / "capture" / "photos" / f"{c.name}.png")


def _run(config: Path, folder: Path, name: str, workers: int, threads: int) -> Path:
    """``harness run`` of ``config`` from ``folder`` (where the scene is), cold; the output folder."""
    out = folder / name
    cmd = [sys.executable, "-m", "harness", "run", str(config), "--out", str(out),
           "--cache", str(folder / f"cache-{name}"), "--workers", str(workers), "--threads", str(threads)]
    path = [str(REPO)] + ([os.environ["PYTHONPATH"]] if os.environ.get("PYTHONPATH") else [])
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(path)}  # this checkout's code, run from another folder
    done = subprocess.run(cmd, cwd=folder, env=env, capture_output=True, text=True, timeout=1200, check=False)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    assert "warning:" not in done.stdout, done.stdout  # every table and plot of the config was made
    record = json.loads((out / "run.json").read_text())["executor"]
    assert (record["workers"], record["threads"]) == (workers, threads)
    return out


def _masked_table(path: Path) -> bytes:
    """A table file with its measured seconds blanked: CSV columns named so and long-format rows of a
    seconds measure; in markdown (``|``) and LaTeX (``&``) tables, the column whose header says so."""
    text = path.read_text()
    if path.suffix == ".csv":
        rows = list(csv.reader(io.StringIO(text)))
        keep = [i for i, h in enumerate(rows[0]) if not SECONDS.match(h)] if rows else []
        buf = io.StringIO()
        csv.writer(buf).writerows([r[i] for i in keep if i < len(r)] for r in rows if "seconds" not in r)
        return buf.getvalue().encode()
    sep = "|" if path.suffix == ".md" else "&"
    name = lambda cell: cell.strip().removesuffix("\\\\").strip()  # noqa: E731 (LaTeX rows end in a double backslash)
    out, blank, width = [], set(), 0
    for line in text.splitlines():
        cells = line.split(sep)
        if not line.strip() or line.startswith("\\end{"):  # a table ends
            blank = set()
        elif len(cells) > 2 and any(SECONDS.match(name(c)) for c in cells):  # its header
            blank, width = {i for i, c in enumerate(cells) if SECONDS.match(name(c))}, len(cells)
        elif blank and len(cells) == width:
            cells = ["" if i in blank else c for i, c in enumerate(cells)]
        out.append(sep.join(cells))
    return "\n".join(out).encode()


def _outputs(out: Path) -> dict[str, bytes | None]:
    """Every table (seconds blanked; the runtime tables, nothing but seconds: None) and every plot."""
    files = {f"tables/{p.name}": None if p.name.startswith("runtime") else _masked_table(p)
             for p in sorted((out / "tables").iterdir())}
    files.update({f"plots/{p.name}": p.read_bytes() for p in sorted((out / "plots").iterdir())})
    return files


def _stored(cache: Path) -> dict[str, object]:
    """Every stage-cache entry: arrays and images as bytes, records as JSON without their measured
    seconds (nor the checksum line that seals them with those seconds)."""
    def strip(v):
        if isinstance(v, dict):
            return {k: strip(x) for k, x in v.items() if not SECONDS.match(k)}
        return [strip(x) for x in v] if isinstance(v, list) else v

    return {str(p.relative_to(cache)): strip(json.loads(p.read_text().partition("\n")[2])) if p.suffix == ".json"
            else p.read_bytes() for p in sorted(cache.rglob("*")) if p.is_file()}


def _same_bytes(config: Path, tmp_path: Path) -> dict[str, bytes | None]:
    """Run ``config`` cold as :data:`RUNS` says; assert the same tables, plots and stage-cache entries
    (scores, masks, renders, every metric of every view). Returns the tables and plots."""
    require_gl()
    if not weights_path().is_file():
        pytest.skip("LPIPS weights absent; run `harness fetch --weights`")
    _world(tmp_path)
    outs = [_run(config, tmp_path, f"w{w}t{t}", w, t) for w, t in RUNS]
    (a, b), (sa, sb) = (_outputs(o) for o in outs), (_stored(o.parent / f"cache-{o.name}") for o in outs)
    assert sorted(a) == sorted(b) and sorted(sa) == sorted(sb)
    differ = [name for name in a if a[name] != b[name]] + [name for name in sa if sa[name] != sb[name]]
    assert not differ, f"{len(differ)} files differ between (workers, threads) {RUNS}: {differ}"
    return a


@pytest.mark.slow
@pytest.mark.gl
@pytest.mark.weights
def test_the_default_study_in_miniature_writes_the_same_bytes_on_other_workers_and_threads(tmp_path):
    files = _same_bytes(CONFIGS / "determinism.yaml", tmp_path)
    config = yaml.safe_load((REPO / "ctc_configs" / "default.yaml").read_text())
    for table in config["tables"]:  # every table of the default study (photos: under `real` only)
        assert any(re.fullmatch(rf"tables/{table}(-[a-z]+)?\.md", name) for name in files), table
    assert sum(name.startswith("plots/") for name in files) >= len(config["plots"])


@pytest.mark.gl
@pytest.mark.weights
def test_thread_sensitive_methods_write_the_same_bytes_on_other_workers_and_threads(tmp_path):
    files = _same_bytes(CONFIGS / "determinism_ci.yaml", tmp_path)
    assert {"tables/comparison.md", "tables/comparison-real.md", "tables/photos-real.md"} <= set(files)


def test_the_miniature_keeps_every_method_protocol_table_and_plot_of_the_default_study():
    """The miniature follows ctc_configs/default.yaml: a method entry, protocol, table or plot added
    there and not here fails this test."""
    from harness.run.config import load_config

    default, mini = load_config(REPO / "ctc_configs" / "default.yaml"), load_config(CONFIGS / "determinism.yaml")
    entries = lambda c: sorted({(m.method, m.variant, m.ratios, m.protocols) for m in c.methods})  # noqa: E731
    assert entries(mini) == entries(default)
    assert [p.name for p in mini.protocols] == [p.name for p in default.protocols]
    assert (mini.tables, mini.plots, mini.protocol.metrics) == (default.tables, default.plots, default.protocol.metrics)
    assert len(mini.scenes) == 1 and mini.scenes[0].capture


def test_a_record_names_the_cpu_it_was_measured_on():
    """Float rounding may differ between CPUs (the GL renderer compiles its shaders for the one it runs
    on), so a run record says which: model name and widest vector extension, as /proc/cpuinfo has them."""
    from harness.report.machine import SIMD_LEVELS, describe_machine

    machine = describe_machine()
    assert isinstance(machine["cpu"], str) and machine["cpu"]
    info = Path("/proc/cpuinfo")
    if not info.is_file():
        pytest.skip("no /proc/cpuinfo on this system")
    text = info.read_text()
    assert machine["cpu"] in text
    flags = next((ln for ln in text.splitlines() if ln.startswith("flags")), "").split()
    assert machine["simd"] == next((f for f in SIMD_LEVELS if f in flags), "")
