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
    from harness.io.safe_yaml import load_yaml

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


# ----------------------------------------------------------------------------- issue 24: every alias of an input
def _one_line(capsys, rc, *phrases):
    out, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert rc == 2 and len(lines) == 1 and "Traceback" not in err, err
    for phrase in phrases:
        assert phrase in lines[0], (phrase, lines[0])
    return lines[0]


def _scene(path: Path, n: int = 200) -> Path:
    from harness.io.ply import write_ply
    from tests.scene_factory import random_scene

    write_ply(random_scene(n, 0, seed=1), path)
    return path


def _bind_mount(src: Path, dst: Path) -> bool:
    """``mount --bind src dst`` (root on Linux); False where it is not allowed."""
    dst.mkdir()
    try:
        return subprocess.run(["mount", "--bind", str(src), str(dst)], capture_output=True).returncode == 0
    except OSError:
        return False


@pytest.mark.parametrize("alias", ["symlinked folder", "hard link", "bind mount"])
def test_prune_never_replaces_its_input_under_another_name(tmp_path, capsys, alias):
    from harness.cli import main

    (tmp_path / "a").mkdir()
    src = _scene(tmp_path / "a" / "s.ply")
    before = src.read_bytes()
    if alias == "symlinked folder":
        (tmp_path / "b").symlink_to(tmp_path / "a")
        out = tmp_path / "b" / "s.ply"
    elif alias == "hard link":
        out = tmp_path / "a" / "h.ply"
        os.link(src, out)
    else:
        if not _bind_mount(tmp_path / "a", tmp_path / "b"):
            pytest.skip("mount --bind is not allowed here (needs root / CAP_SYS_ADMIN)")
        out = tmp_path / "b" / "s.ply"
    try:
        rc = main(["prune", str(src), str(out), "--ratio", "0.3", "--method", "opacity"])
        _one_line(capsys, rc, f"harness: {out}: would overwrite the input {src}")
    finally:
        if alias == "bind mount":
            subprocess.run(["umount", str(tmp_path / "b")], check=True)
    assert src.read_bytes() == before and not list(tmp_path.rglob(".*.tmp"))


def test_render_never_rewrites_the_camera_file_it_read(tmp_path, capsys):
    """`render g.ply --cameras v16/cameras.json --out v16`: refused before any image is written."""
    from harness.cli import main
    from harness.core.cameras import Camera
    from harness.io.cameras import write_3dgs_cameras

    src = _scene(tmp_path / "g.ply")
    v16 = tmp_path / "v16"
    cams = [Camera.look_at((4 * np.cos(a), 0.5, 4 * np.sin(a)), (0, 0, 0), width=32, height=24, name=f"c{i}")
            for i, a in enumerate(np.linspace(0, 6, 16))]
    write_3dgs_cameras(cams, v16 / "cameras.json")
    before = sorted(p.name for p in v16.iterdir()), (v16 / "cameras.json").read_bytes()
    rc = main(["render", str(src), "--cameras", str(v16 / "cameras.json"), "--out", str(v16), "--split", "all"])
    _one_line(capsys, rc, "would overwrite the input", "cameras.json")
    assert (sorted(p.name for p in v16.iterdir()), (v16 / "cameras.json").read_bytes()) == before


def test_plan_out_over_its_config_or_a_scene_is_refused_naming_the_path_given(tmp_path, capsys, monkeypatch):
    from harness.cli import main
    from tests.stress.cases import _config

    monkeypatch.chdir(tmp_path)
    cfg = _config(tmp_path)
    for target in (cfg, tmp_path / "s.ply"):
        before = target.read_bytes()
        line = _one_line(capsys, main(["plan", str(cfg), "--out", str(target)]), f"harness: {target}: would overwrite")
        assert ".tmp" not in line and target.read_bytes() == before
    (tmp_path / "dir.json").mkdir()
    line = _one_line(capsys, main(["plan", str(cfg), "--out", str(tmp_path / "dir.json")]))
    assert line.startswith(f"harness: {tmp_path / 'dir.json'}: ") and ".tmp" not in line


def test_state_read_to_be_updated_is_not_an_input(tmp_path):
    """A tracking baseline is read (record=False) and then rewritten by --update-baseline."""
    from harness.io.files import atomic_write_text, refuse_inputs
    from harness.io.safe import read_json, recording_inputs

    state, data = tmp_path / "baseline.json", tmp_path / "data.json"
    state.write_text("{}")
    data.write_text("{}")
    with recording_inputs():
        read_json(state, record=False)
        read_json(data)
        atomic_write_text(state, "{}\n")
        with pytest.raises(InputError, match="would overwrite the input"):
            refuse_inputs(tmp_path / "." / "data.json")
    refuse_inputs(data)  # outside a command nothing is recorded


@pytest.mark.parametrize("kind", ["fifo", "symlink", "folder"])
def test_history_appends_only_to_a_regular_file(tmp_path, kind):
    import time

    from harness.io.files import append_line

    victim = tmp_path / "victim.txt"
    victim.write_text("keep\n")
    p = tmp_path / "history.jsonl"
    {"fifo": lambda: os.mkfifo(p), "symlink": lambda: p.symlink_to(victim), "folder": p.mkdir}[kind]()
    t0 = time.perf_counter()
    with pytest.raises(InputError, match="expected a regular file to append to"):
        append_line(p, "{}\n")
    assert time.perf_counter() - t0 < 1 and victim.read_text() == "keep\n"
    q = tmp_path / "new.jsonl"
    append_line(q, "a\n")
    append_line(q, "b\n")
    assert q.read_text() == "a\nb\n" and q.stat().st_mode & 0o777 == 0o666 & ~_umask()


def _umask() -> int:
    old = os.umask(0)
    os.umask(old)
    return old


# ----------------------------------------------------------------------------- the CLI's last resort
def test_an_unexpected_exception_is_one_line_and_debug_shows_the_traceback(capsys, monkeypatch, tmp_path):
    from harness.cli import main
    from harness.commands import info

    def boom(args):
        from harness.io.safe import read_bytes

        read_bytes(src)
        raise ZeroDivisionError("division by zero")

    src = tmp_path / "x.bin"
    src.write_bytes(b"1")
    monkeypatch.setattr(info, "run", boom)
    line = _one_line(capsys, main(["info", "whatever"]), "harness: info: ZeroDivisionError: division by zero",
                     f"(last input read: {src})", "--debug")
    assert main(["info", "whatever", "--debug"]) == 2
    err = capsys.readouterr().err
    assert "Traceback" in err and err.strip().splitlines()[-1] == line


def test_a_config_with_a_control_character_or_nul_is_one_line(tmp_path, capsys):
    from harness.cli import main

    for bad in (b"name: t\x00\n", b"name: t\x07x\n"):
        (tmp_path / "c.yaml").write_bytes(bad)
        _one_line(capsys, main(["run", str(tmp_path / "c.yaml")]), "invalid YAML", "control character or NUL")
    assert not (tmp_path / "out").exists()


def test_a_ray_address_nobody_answers_fails_fast_before_the_output_folder(tmp_path, capsys, monkeypatch):
    import time

    from harness.cli import main
    from tests.stress.cases import _config

    monkeypatch.chdir(tmp_path)
    cfg = _config(tmp_path)
    t0 = time.perf_counter()
    rc = main(["run", str(cfg), "--address", "127.0.0.1:1", "--out", str(tmp_path / "o")])
    _one_line(capsys, rc, "--address: 127.0.0.1:1: cannot connect")
    assert time.perf_counter() - t0 < 15 and not (tmp_path / "o").exists()


# ----------------------------------------------------------------------------- sizes where they enter
def test_no_camera_larger_than_the_maximum_can_be_made():
    from harness.core.cameras import MAX_SIDE, Camera, CameraSizeError

    ok = Camera.look_at((0, 0, -4), (0, 0, 0), width=MAX_SIDE, height=16)
    with pytest.raises(CameraSizeError, match="larger than the maximum render size"):
        Camera.look_at((0, 0, -4), (0, 0, 0), width=16384, height=1080, name="v0")
    with pytest.raises(ValueError):  # stored camera dicts fail their schema check the same way
        Camera.from_dict({**ok.to_dict(), "width": 12000, "height": 12000})
    with pytest.raises(InputError):
        Camera.look_at((0, 0, -4), (0, 0, 0), width=0, height=16)


def test_header_camera_size_line_beyond_the_maximum_is_refused(tmp_path, capsys):
    from harness.cli import main
    from harness.io.gscameras import cameras_from_lines

    with pytest.raises(InputError, match="12000 x 12000 pixels is larger"):
        cameras_from_lines(["camera_position_resolution 12000 12000"], "x.ply")
    src = _scene(tmp_path / "s.ply")
    _one_line(capsys, main(["score", str(src), str(src), "--width", "16384", "--height", "1080"]),
              "16384 x 1080 pixels is larger than the maximum render size")


def test_ply_header_is_parsed_in_linear_time_with_a_property_cap(tmp_path):
    import time

    from harness.io.ply import read_ply_header

    data = _scene(tmp_path / "s.ply", 10).read_bytes()
    many = tmp_path / "many.ply"
    many.write_bytes(data.replace(b"end_header\n", b"".join(b"property float e%d\n" % i for i in range(50_000))
                                  + b"end_header\n", 1))
    t0 = time.perf_counter()
    with pytest.raises(InputError, match="more than 4,096 properties"):
        read_ply_header(many)
    comments = tmp_path / "comments.ply"
    comments.write_bytes(data.replace(b"end_header\n", b"comment x\n" * 90_000 + b"end_header\n", 1))
    assert len(read_ply_header(comments).comments) == 90_000
    assert time.perf_counter() - t0 < 5  # 20,000 properties took 36 s when names were compared pairwise
