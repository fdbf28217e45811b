"""Everyday commands import only what they run (issue 25): most of a short command's time was
start-up — every command module's libraries for the parser, torch for ``--device cpu``, scipy.stats
for a normalisation not in use. Each command runs here in a fresh interpreter and the heavy
libraries it loaded are read from ``sys.modules`` afterwards."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from harness.io.scenes import write_scene
from tests.gl_support import require_gl
from tests.scene_factory import random_scene

REPO = Path(__file__).resolve().parent.parent
HEAVY = ("torch", "pandas", "pyarrow", "matplotlib", "scipy.stats", "scipy.ndimage", "torchvision", "lpips", "rich",
         "triton")
_PROBE = """
import json, sys
from harness.cli import main
try:
    status = main(sys.argv[1:])
except SystemExit as stop:
    status = stop.code
print(json.dumps({"status": status, "loaded": [m for m in %r if m in sys.modules]}), file=sys.stderr)
""" % (HEAVY,)


def loaded_by(*argv) -> list[str]:
    """The heavy modules ``harness ARGV`` imported, run in a fresh interpreter (it must succeed)."""
    done = subprocess.run([sys.executable, "-c", _PROBE, *map(str, argv)], cwd=REPO, capture_output=True, text=True)
    report = json.loads(done.stderr.strip().splitlines()[-1])
    assert report["status"] == 0, done.stderr
    return report["loaded"]


@pytest.fixture(scope="module")
def scene(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("lean") / "s.ply"
    write_scene(random_scene(3000, sh_degree=3, seed=5), path)
    return path


def test_prune_imports_no_torch_pandas_or_matplotlib(scene, tmp_path):
    """Nor scipy.stats (only the rank normalisation uses it) or scipy.ndimage."""
    assert loaded_by("prune", scene, tmp_path / "o.ply", "--ratio", "0.3") == []
    assert loaded_by("prune", scene, tmp_path / "o.spz", "--keep", "0.5", "--method", "opacity", "--json") == []


def test_info_help_and_psnr_import_nothing_heavy(scene, tmp_path):
    from PIL import Image

    assert loaded_by("info", scene) == []
    assert loaded_by("info", scene, "--json") == []
    assert loaded_by("--help") == [] and loaded_by("bench", "--help") == []
    assert loaded_by("prune", "--help") == []
    img = (np.random.default_rng(0).random((16, 16, 3)) * 255).astype(np.uint8)
    Image.fromarray(img).save(tmp_path / "a.png")
    assert loaded_by("compare", tmp_path / "a.png", tmp_path / "a.png", "--metrics", "psnr") == []
    if not Path("/dev/nvidiactl").exists():  # SSIM's numpy form on the CPU (torch on a GPU machine)
        assert loaded_by("compare", tmp_path / "a.png", tmp_path / "a.png", "--metrics", "ssim,psnr") == []


@pytest.mark.gl
def test_render_imports_nothing_heavy(scene, tmp_path):
    """Not torch either: the GL renderer projects and sorts the splats with numpy on a machine
    without an NVIDIA GPU (renderers.arrays), the rig is placed without scipy.ndimage, and a
    one-shot render does not preload triton (it never calls torch.compile)."""
    from pathlib import Path

    require_gl()
    loaded = loaded_by("render", scene, "--rig", "orbit", "--longest-side", "24", "--n-test", "1", "--n-train", "0",
                       "--out", tmp_path / "r")
    on_gpu = Path("/dev/nvidiactl").exists()  # there torch projects on CUDA
    assert [m for m in loaded if not (on_gpu and m == "torch")] == [], loaded


def test_the_probe_sees_what_a_command_imports(tmp_path):
    """The check can fail: `harness methods` prints with rich, and the probe says so."""
    assert "rich" in loaded_by("methods")
