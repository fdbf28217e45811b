"""The Python API (`harness.load/save/info/score/prune/render/compare/evaluate/methods`) gives what
the commands give — the same bytes, values and rows — and the same one-line errors, naming its
keyword arguments where the commands name their flags."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

import harness
from harness.cli import main
from harness.io.datasets import scene_path
from harness.io.scenes import write_scene
from tests import runner_fakes as fakes
from tests.gl_support import require_gl
from tests.scene_factory import random_scene

REPO = Path(__file__).resolve().parent.parent


def _luigi():
    if not scene_path("luigi").exists():
        pytest.skip("luigi is not fetched (`harness fetch luigi`)")
    return "luigi"


def test_import_harness_is_cheap_and_lists_the_api():
    code = ("import sys, harness; heavy = [m for m in ('numpy', 'torch', 'pandas', 'harness.api') if m in sys.modules];"
            " print(heavy, sorted(harness.__all__), callable(harness.prune))")
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, check=True).stdout
    assert out.startswith(
        "[] ['HarnessError', 'Pruned', 'Scene', 'cameras', 'compare', 'evaluate', 'info', 'load', 'methods', "
        "'prune', 'render', 'save', 'score'] True"
    ), out
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        harness.nope  # noqa: B018


@pytest.mark.data
@pytest.mark.parametrize("cli, api", [
    (["--ratio", "0.3"], {"ratio": 0.3}),
    (["--keep", "0.5", "--voxel", "0.1"], {"keep": 0.5, "voxel": 0.1}),
    (["--ratio", "0.2", "--method", "opacity"], {"ratio": 0.2, "method": "opacity"}),
    (["--ratio", "0"], {"ratio": 0}),
])
def test_prune_is_the_commands_prune_byte_for_byte(tmp_path, capsys, cli, api):
    name = _luigi()
    assert main(["prune", name, str(tmp_path / "cli.ply"), *cli, "--scores", str(tmp_path / "cli.npy"),
                 "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    pruned = harness.prune(harness.load(name), **api)
    harness.save(pruned.scene, tmp_path / "api.ply")
    assert (tmp_path / "api.ply").read_bytes() == (tmp_path / "cli.ply").read_bytes()
    assert (pruned.removed, pruned.kept, pruned.method, pruned.params) == \
        (report["removed"], report["splats_out"], report["method"], report["params"])
    assert pruned.tau == (report["tau"] if report["tau"] is not None else float("-inf"))
    if api.get("ratio") == 0:  # nothing removed, nothing scored; the command scores for --scores
        assert pruned.scores is None and pruned.mask.all()
    else:
        np.testing.assert_array_equal(pruned.scores, np.load(tmp_path / "cli.npy"))
        params = {k: v for k, v in api.items() if k not in ("ratio", "keep", "method")}
        np.testing.assert_array_equal(pruned.scores, harness.score(name, pruned.method, **params))


def test_pruned_holds_the_cut():
    scene = random_scene(400, seed=3)
    p = harness.prune(scene, ratio=0.25, method="opacity")
    assert p.mask.dtype == bool and p.mask.shape == (400,) and p.removed == 100 == 400 - p.kept
    assert p.scores.dtype == np.float64 and p.tau == p.scores[~p.mask].max() <= p.scores[p.mask].min()
    np.testing.assert_array_equal(p.scene.means, scene.means[p.mask])
    assert set(p.seconds) == {"score", "select"}  # a scene given: nothing read
    assert "read" in harness.prune(_write(scene), keep=0.9, method="opacity").seconds


def _write(scene, folder=None) -> str:
    import tempfile

    path = Path(folder or tempfile.mkdtemp()) / "s.ply"
    write_scene(scene, path)
    return str(path)


@pytest.mark.parametrize("kwargs, message, argv, line", [
    ({"ratio": 2}, "ratio: must be a number in [0, 1], got 2", ["--ratio", "2"],
     "--ratio: must be a number in [0, 1], got 2.0"),
    ({"keep": -1}, "keep: must be a number in [0, 1], got -1", ["--keep", "-1"],
     "--keep: must be a number in [0, 1], got -1.0"),
    ({"ratio": 0.3, "method": "lightgss"}, "method: unknown pruner 'lightgss' (did you mean 'lightgs'?)",
     ["--ratio", "0.3", "--method", "lightgss"], "--method: unknown pruner 'lightgss' (did you mean 'lightgs'?)"),
    ({"ratio": 0.3, "voxel": -1}, "voxel: method 'betadesc': -1.0 is not > 0", ["--ratio", "0.3", "--voxel", "-1"],
     "--voxel: method 'betadesc': -1.0 is not > 0"),
    ({"ratio": 0.3, "method": "lightgs"}, "cameras: 'lightgs' needs training cameras; none were given",
     ["--ratio", "0.3", "--method", "lightgs"], "--cameras: 'lightgs' needs training cameras; none were given"),
    ({"ratio": 0.3, "device": "meta"}, "device: device type 'meta' cannot run the harness",
     ["--ratio", "0.3", "--device", "meta"], "--device: device type 'meta' cannot run the harness"),
])
def test_errors_are_the_commands_errors(tmp_path, capsys, kwargs, message, argv, line):
    """The same mistake is the same one line: the API names the argument, the command its flag."""
    path = _write(random_scene(50, seed=1), tmp_path)
    with pytest.raises(harness.HarnessError) as info:
        harness.prune(path, **kwargs)
    assert str(info.value).startswith(message), str(info.value)
    assert main(["prune", path, str(tmp_path / "o.ply"), *argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"harness: {line}") and err.count("\n") == 1, err
    assert not (tmp_path / "o.ply").exists()


def test_other_errors_name_the_argument(tmp_path):
    scene = random_scene(20, seed=2)
    cases = [
        (lambda: harness.prune(scene), "ratio: give exactly one of ratio"),
        (lambda: harness.prune(scene, ratio=0.1, keep=0.9), "ratio: give exactly one of ratio"),
        (lambda: harness.prune(42, ratio=0.1), "scene: expected a scene, a path or a scene name, got int"),
        (lambda: harness.load(tmp_path / "none.ply"), f"{tmp_path / 'none.ply'}: no such file or folder"),
        (lambda: harness.save(scene, tmp_path / "x.obj"), "x.obj"),
        (lambda: harness.save(scene, tmp_path / "no" / "x.ply"), "output folder does not exist"),
        (lambda: harness.compare(np.zeros((4, 4, 3)), np.zeros((4, 5, 3)), "psnr"),
         "first image vs second image: image sizes differ"),
        (lambda: harness.compare(np.zeros((4, 4, 3)), np.zeros((4, 4, 3)), "psnrr"),
         "metrics: unknown metric or family 'psnrr' (did you mean 'psnr'"),
        (lambda: harness.render(scene, []), "cameras: expected a camera file"),
        (lambda: harness.render(scene, tmp_path / "no.json"), "no such file or folder"),
        (lambda: harness.evaluate(tmp_path / "no.yaml"), "cannot read config: no such file"),
    ]
    for call, text in cases:
        with pytest.raises(harness.HarnessError) as info:
            call()
        assert text in str(info.value) and "\n" not in str(info.value), (text, str(info.value))


def test_save_never_replaces_the_file_a_scene_came_from(tmp_path):
    path = _write(random_scene(30, seed=4), tmp_path)
    before = Path(path).read_bytes()
    pruned = harness.prune(path, ratio=0.5, method="opacity")
    with pytest.raises(harness.HarnessError, match="would overwrite the input"):
        harness.save(pruned.scene, path)
    assert Path(path).read_bytes() == before
    assert harness.save(path, tmp_path / "copy.splat") == tmp_path / "copy.splat"  # a path is read, then written
    assert len(harness.load(tmp_path / "copy.splat")) == 30


def test_info_and_methods_are_what_the_commands_print(tmp_path, capsys):
    path = _write(random_scene(60, seed=5), tmp_path)
    assert main(["info", path, "--json"]) == 0
    assert json.loads(capsys.readouterr().out) == json.loads(json.dumps(harness.info(path)))
    assert harness.info(harness.load(path))["splats"] == 60
    assert main(["methods", "--json"]) == 0
    assert json.loads(capsys.readouterr().out) == json.loads(json.dumps(harness.methods()))


def _images(tmp_path):
    from PIL import Image

    rng = np.random.default_rng(0)
    a = (rng.random((24, 40, 3)) * 255).astype(np.uint8)
    b = np.clip(a.astype(int) + rng.integers(-9, 10, a.shape), 0, 255).astype(np.uint8)
    Image.fromarray(a).save(tmp_path / "a.png")
    Image.fromarray(b).save(tmp_path / "b.png")
    return a, b


def _printed(values: dict) -> dict:
    """``values`` as `harness compare --json` prints them."""
    from harness.commands.compare import _json_ready

    return json.loads(json.dumps(_json_ready(values)))


@pytest.mark.parametrize("metrics, extra", [("psnr", []), ("mpeg", []), ("mpeg", ["--qmiv"]), ("psnr,ssim", ["--yuv"])])
def test_compare_is_the_commands_compare(tmp_path, capsys, metrics, extra):
    a, b = _images(tmp_path)
    assert main(["compare", str(tmp_path / "a.png"), str(tmp_path / "b.png"), "--metrics", metrics, "--json",
                 *extra]) == 0
    cli = json.loads(capsys.readouterr().out)
    options = {"qmiv": "--qmiv" in extra, "yuv": "--yuv" in extra}
    as_float = lambda u8: u8.astype(np.float32) / np.float32(255)  # noqa: E731  what reading the PNG gives
    for first, second in ((tmp_path / "a.png", tmp_path / "b.png"), (a, b), (as_float(a), as_float(b))):
        assert _printed(harness.compare(first, second, metrics, **options)) == cli


def test_compare_with_a_mask(tmp_path, capsys):
    a, b = _images(tmp_path)
    mask = np.zeros(a.shape[:2], bool)
    mask[4:20, 5:30] = True
    from PIL import Image

    Image.fromarray(mask.astype(np.uint8) * 255).save(tmp_path / "m.png")
    assert main(["compare", str(tmp_path / "a.png"), str(tmp_path / "b.png"), "--metrics", "mpeg", "--mask",
                 str(tmp_path / "m.png"), "--json"]) == 0
    cli = json.loads(capsys.readouterr().out)
    for m in (mask, tmp_path / "m.png"):
        values = harness.compare(a, b, "mpeg", mask=m)
        assert values["occupancy"] == pytest.approx(100 * mask.mean())
        assert _printed(values) == cli


def test_compare_for_psnr_alone_imports_no_torch(tmp_path):
    _images(tmp_path)
    code = ("import sys, harness; v = harness.compare(sys.argv[1], sys.argv[2], 'psnr'); "
            "print(round(v['psnr'], 6), 'torch' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code, str(tmp_path / "a.png"), str(tmp_path / "b.png")], cwd=REPO,
                         capture_output=True, text=True, check=True).stdout
    assert out.split()[1] == "False", out


@pytest.mark.gl
def test_render_is_the_commands_render(tmp_path, capsys):
    require_gl()
    path = _write(random_scene(300, sh_degree=1, seed=6), tmp_path)
    assert main(["render", path, "--rig", "orbit", "--longest-side", "40", "--n-test", "2", "--n-train", "0",
                 "--format", "npy", "--background", "0.1,0.2,0.3", "--out", str(tmp_path / "r")]) == 0
    capsys.readouterr()
    files = sorted((tmp_path / "r").glob("0*.npy"))
    images = harness.render(path, tmp_path / "r" / "cameras.json", background=(0.1, 0.2, 0.3))
    assert len(images) == len(files) == 2
    rig = harness.cameras(path, "orbit", longest_side=40, n_test=2, n_train=0)
    written = harness.cameras(path, cameras=tmp_path / "r" / "cameras.json")  # the file keeps them to ~1e-15
    assert [(c.name, c.width, c.height) for c in rig] == [(c.name, c.width, c.height) for c in written]
    np.testing.assert_allclose([c.world_to_cam for c in rig], [c.world_to_cam for c in written], atol=1e-12)
    for img, again, f in zip(images, harness.render(path, rig, background=(0.1, 0.2, 0.3)), files):
        np.testing.assert_array_equal(img, np.load(f))
        np.testing.assert_array_equal(again, img)
    with pytest.raises(harness.HarnessError, match="longest_side: must be a whole number from 1 to 8192"):
        harness.cameras(path, longest_side=0)
    with pytest.raises(harness.HarnessError, match="background: expected three numbers"):
        harness.render(path, tmp_path / "r" / "cameras.json", background=(2, 0, 0))


@pytest.mark.gl
def test_evaluate_returns_the_rows_the_command_writes(tmp_path, capsys):
    require_gl()
    from harness.report.results import read_results

    scenes = fakes.write_two_scenes(tmp_path)
    doc = {"name": "api", "protocol": {"longest_side": 24, "metrics": ["psnr"], "n_train": 2, "n_test": 2},
           "ratios": [0.3], "scenes": [{"name": k, "source": v} for k, v in scenes.items()],
           "methods": ["opacity", "random"], "tables": ["comparison"], "plots": []}
    config = tmp_path / "c.yaml"
    config.write_text(yaml.safe_dump(doc))
    cache = str(tmp_path / "cache")
    rows = harness.evaluate(config, out=tmp_path / "api", cache=cache)
    capsys.readouterr()
    assert len(rows) == 8 and (rows["status"] == "ok").all()
    assert rows.equals(read_results(tmp_path / "api"))
    assert main(["run", str(config), "--out", str(tmp_path / "cli"), "--cache", cache]) == 0
    measured = ["scene", "method", "ratio", "view", "psnr", "splats_out", "tau"]
    assert read_results(tmp_path / "cli")[measured].equals(rows[measured])
    assert harness.evaluate(doc, out=tmp_path / "dict", cache=cache)[measured].equals(rows[measured])


@pytest.mark.gl
def test_evaluate_logs_and_prints_nothing_the_command_shows_the_same_lines(tmp_path, capfd, caplog):
    """`harness.evaluate` wrote `harness run tiny: 1 scenes, ...` to stderr: a library call logs (logger
    `harness.run`), and `harness run` shows those records."""
    import logging

    require_gl()
    scenes = fakes.write_two_scenes(tmp_path)
    doc = {"name": "tiny", "protocol": {"longest_side": 16, "metrics": ["psnr"], "n_train": 2, "n_test": 1},
           "ratios": [0.3], "scenes": [{"name": k, "source": v} for k, v in list(scenes.items())[:1]],
           "methods": ["opacity"], "tables": [], "plots": []}
    config = tmp_path / "tiny.yaml"
    config.write_text(yaml.safe_dump(doc))
    cache = str(tmp_path / "cache")
    capfd.readouterr()
    with caplog.at_level(logging.INFO, logger="harness.run"):
        harness.evaluate(config, out=tmp_path / "api", cache=cache)
    out, err = capfd.readouterr()
    assert out == "" and err == "", (out, err)
    logged = [r.getMessage() for r in caplog.records if r.name == "harness.run"]
    assert logged[0].startswith("harness run tiny: 1 scenes, 1 method variants, 1 worker(s) -> ")
    stages = [m for m in logged if m.endswith(" to compute")]
    assert "score: 1 to compute" in stages
    caplog.clear()
    assert main(["run", str(config), "--out", str(tmp_path / "cli"), "--cache", str(tmp_path / "cache2")]) == 0
    err = capfd.readouterr().err.splitlines()
    assert err[0].startswith("harness run tiny: 1 scenes, 1 method variants, 1 worker(s) -> ")
    assert [ln for ln in err if ln.endswith(" to compute")] == stages
    harness.evaluate(config, out=tmp_path / "again", cache=cache)  # after the command: still silent
    assert capfd.readouterr() == ("", "")


@pytest.mark.gl
def test_a_cached_rerun_into_the_same_folder_keeps_its_tables_and_plots(tmp_path, monkeypatch):
    """The run stages its outputs and publishes them in one step: the memo and the tables it keeps must
    reach the staging folder, or every cached rerun rebuilds every table."""
    from harness.report import memo, outputs

    require_gl()
    scenes = fakes.write_two_scenes(tmp_path)
    doc = {"name": "tiny", "protocol": {"longest_side": 16, "metrics": ["psnr"], "n_train": 2, "n_test": 1},
           "ratios": [0.3], "scenes": [{"name": k, "source": v} for k, v in list(scenes.items())[:1]],
           "methods": ["opacity", "random"], "tables": ["comparison"], "plots": ["curves"]}
    out, cache = tmp_path / "out", str(tmp_path / "cache")
    harness.evaluate(doc, out=out, cache=cache)
    assert (out / memo.FOLDER / memo.NAME).is_file()
    table = (out / "tables" / "comparison.md").read_bytes()

    def fail(*a, **k):
        raise AssertionError("rebuilt although nothing changed")

    monkeypatch.setattr(outputs, "write_tables", fail)
    monkeypatch.setattr(outputs, "write_plots", fail)
    harness.evaluate(doc, out=out, cache=cache)
    assert (out / "tables" / "comparison.md").read_bytes() == table and (out / memo.FOLDER / memo.NAME).is_file()


@pytest.mark.gl
def test_a_rerun_with_fewer_tables_leaves_none_of_the_earlier_ones(tmp_path):
    """The rerun stages the earlier outputs (for the memo); when it rebuilds, a table its config no longer
    names is not carried into the new publication."""
    require_gl()
    scenes = fakes.write_two_scenes(tmp_path)
    doc = {"name": "tiny", "protocol": {"longest_side": 16, "metrics": ["psnr"], "n_train": 2, "n_test": 1},
           "ratios": [0.3], "scenes": [{"name": k, "source": v} for k, v in list(scenes.items())[:1]],
           "methods": ["opacity", "random"], "tables": ["comparison", "runtime"], "plots": ["curves"]}
    out, cache = tmp_path / "out", str(tmp_path / "cache")
    harness.evaluate(doc, out=out, cache=cache)
    assert (out / "tables" / "runtime.md").is_file() and any((out / "plots").iterdir())
    harness.evaluate({**doc, "tables": ["comparison"], "plots": []}, out=out, cache=cache)
    assert (out / "tables" / "comparison.md").is_file() and not (out / "tables" / "runtime.md").exists()
    assert not (out / "plots").exists() or not any((out / "plots").iterdir()), list((out / "plots").iterdir())
