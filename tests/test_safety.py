"""Issue 15 building blocks: strict JSON, temp-file sweeping, confinement, YAML limits, devices,
worker-count determinism of the metrics, and the verified cache inside a real run."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from harness.core.errors import InputError


def test_jsonout_is_strict_json():
    from harness.core.jsonout import dumps

    text = dumps({"a": float("inf"), "b": [float("nan"), 1.5, np.float32(-np.inf)], "c": np.arange(3),
                  "d": np.float64(2.0)})
    assert json.loads(text, parse_constant=lambda c: pytest.fail(c)) == {"a": None, "b": [None, 1.5, None],
                                                                          "c": [0, 1, 2], "d": 2.0}


def test_sweep_removes_temp_files_of_dead_pids_only(tmp_path):
    from harness.io.files import _host, sweep_stale_temps, temp_path

    mine = temp_path(tmp_path / "out.ply")  # this (live) process
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    gone = tmp_path / f".out.ply.{_host()}.{int(dead.stdout)}.abc123.tmp"
    gone.write_bytes(b"partial")
    other_host = tmp_path / ".out.ply.elsewhere.1.abc.tmp"
    other_host.write_bytes(b"maybe still being written")
    unrelated = tmp_path / ".hidden.tmp"
    unrelated.write_bytes(b"not ours")
    assert sweep_stale_temps(tmp_path) == 1
    assert mine.exists() and not gone.exists() and other_host.exists() and unrelated.exists()
    os.utime(other_host, (0, 0))  # a day old: its writer is gone too
    assert sweep_stale_temps(tmp_path) == 1 and not other_host.exists()


def test_confined_paths(tmp_path):
    from harness.io.safe import confined

    (tmp_path / "a").mkdir()
    assert confined(tmp_path, "a/x.webp", "m") == (tmp_path / "a" / "x.webp").resolve()
    assert confined(tmp_path, "a/../b.webp", "m") == (tmp_path / "b.webp").resolve()
    for bad in ("../x", "/etc/passwd", "a/../../x", "", "a\x00b"):
        with pytest.raises(InputError):
            confined(tmp_path, bad, "m")
    (tmp_path / "link").symlink_to("/etc")
    with pytest.raises(InputError, match="outside"):
        confined(tmp_path, "link/passwd", "m")


def test_yaml_duplicate_keys_and_aliases(tmp_path):
    from harness.io.safe import load_yaml

    p = tmp_path / "c.yaml"
    p.write_text("a: 1\nb: {x: 1, x: 2}\n")
    with pytest.raises(InputError, match="duplicate key 'x'"):
        load_yaml(p)
    p.write_text("base: &b {gamma: 0.25}\nm: [*b, *b]\n")  # ordinary anchors still work
    assert load_yaml(p)["m"] == [{"gamma": 0.25}, {"gamma": 0.25}]


@pytest.mark.parametrize("text", ["meta", "xla", "nonsense:0", "cuda:99"])
def test_devices_refused_before_work(text):
    import torch

    from harness.core.devices import check_device

    if text.startswith("cuda") and torch.cuda.is_available() and torch.cuda.device_count() > 99:
        pytest.skip("a machine with 100 GPUs")
    with pytest.raises(InputError):
        check_device(text)
    assert check_device("cpu") == "cpu" and check_device(None) is None


def test_ssim_does_not_depend_on_the_thread_count():
    """1 and 2 workers give each worker cores // workers torch threads; SSIM must not change."""
    import torch

    from harness.metrics.ssim import ssim

    rng = np.random.default_rng(0)
    a = rng.random((384, 512, 3)).astype(np.float32)
    b = np.clip(a + rng.normal(0, 0.05, a.shape), 0, 1).astype(np.float32)
    before = torch.get_num_threads()
    try:
        values = []
        for threads in (1, 2, 3):
            torch.set_num_threads(threads)
            values.append(ssim(a, b))
    finally:
        torch.set_num_threads(before)
    assert values[0] == values[1] == values[2]


def test_png_16bit_grey_alpha_refused(tmp_path):
    from harness.metrics.images import read_image
    from tests.stress.cases import _png

    p = _png(tmp_path / "la.png", 4, 4, 4, 16)
    with pytest.raises(InputError, match="16-bit grey\\+alpha"):
        read_image(p)


@pytest.mark.slow
def test_results_are_bit_identical_for_one_and_two_workers(tmp_path):
    import pandas as pd

    from tests.stress.experiments import STUDY

    scene = Path(os.environ.get("HARNESS_SHARED_DATA", "/work/shared/data")) / "grape_small.ply"
    if not scene.is_file():
        pytest.skip("grape_small.ply is not in the shared data folder")
    cfg = tmp_path / "s.yaml"
    cfg.write_text(STUDY.replace("RATIOS", "[0.1, 0.3]").replace("SCENE", str(scene))
                   .replace("longest_side: 64", "longest_side: 256"))
    frames = []
    for w in (1, 2):
        r = subprocess.run([sys.executable, "-m", "harness", "run", str(cfg), "--workers", str(w), "--cache",
                            str(tmp_path / f"c{w}"), "--out", str(tmp_path / f"o{w}")], capture_output=True, text=True,
                           cwd=tmp_path, timeout=900)
        assert r.returncode == 0, r.stderr[-2000:]
        df = pd.read_parquet(tmp_path / f"o{w}" / "results.parquet")
        frames.append(df.sort_values(["method", "ratio", "view"])[["psnr", "ssim", "lpips"]].to_numpy())
    assert np.array_equal(frames[0], frames[1])
