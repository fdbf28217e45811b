"""Every number finite or refused, and the Python API held to the command line's rules (registered
into :data:`tests.stress.cases.CASES`): families **F** and **Y**.

* **F**: a scene far beyond what the float32 render pipeline holds (splat centres × 1e18 made NaN
  cameras, black renders and PSNR inf counted as perfect), one far inside it (× 1e10, which must
  still render), a scene far from the origin for its size (float32 rounds its centres to a few
  points), the MPEG set on images smaller than its windows (``nan`` printed, invalid JSON, an
  ``IndexError``), a plugin metric that returns NaN, ``harness track`` on a group whose SSIM is
  NaN on every view, ``diagnose`` of the far scene (``significance nan%``).
* **Y**: Python code calling the API as a user would — scenes built or changed in memory (NaN
  opacities, mismatched lengths, float64 arrays, no splats), arguments of the wrong type or range
  (``ratio=True``, ``seed=1.5``, ``seed=-5``, ``longest_side='256'`` or ``1.5``, ``n_test=2.5``,
  ``workers=1.5``), a camera with a NaN pose. Each must be one :class:`harness.HarnessError` naming
  the argument (the code prints it as the CLI does and exits 2), never another exception, a
  written file or a wrong result.
"""

from __future__ import annotations

import json
import sys
import textwrap
from pathlib import Path

import numpy as np

from tests.stress.cases import ROOT, Setup, _config, _png, _run_dir, case
from tests.stress.cases_plugins import _plugin


def _scaled(d: Path, factor: float, name: str = "far.ply", n: int = 300) -> Path:
    """A random scene with every length (centres and splat sizes) multiplied by ``factor``."""
    sys.path.insert(0, str(ROOT))
    from harness.core.scene import GaussianScene
    from harness.io.ply import write_ply
    from tests.scene_factory import random_scene

    s = random_scene(n, 0, seed=1)
    scaled = GaussianScene.from_arrays(s.means * factor, s.scales_log + np.log(factor), s.quats, s.opacity_logit,
                                       s.sh_dc)
    write_ply(scaled, d / name)
    return d / name


def _finite_cameras(out: Path):
    def check() -> str | None:
        if not (out / "cameras.json").is_file():
            return "no cameras.json"
        try:
            text = (out / "cameras.json").read_text()
            json.loads(text, parse_constant=lambda c: (_ for _ in ()).throw(ValueError(c)))
        except ValueError as err:
            return f"cameras.json is not strict JSON ({err})"
        return None
    return check


# ============================================================================ F: finite or refused
@case("F1", "numbers", "render a scene whose splats lie at 1e17..1e18 (NaN cameras, black views, exit 0)")
def _(d):
    s = _scaled(d, 1e18)
    return Setup(["render", str(s), "--longest-side", "32", "--out", str(d / "o")], unchanged=[s], absent=[d / "o"])


@case("F2", "numbers", "render the same scene scaled by 1e10: finite cameras, strict JSON", want="ok")
def _(d):
    s = _scaled(d, 1e10)
    return Setup(["render", str(s), "--longest-side", "32", "--n-test", "2", "--out", str(d / "o")], unchanged=[s],
                 check=_finite_cameras(d / "o"))


@case("F3", "numbers", "run: one scene × 1e18 beside a good one (PSNR inf counted as perfect)", want="scene error",
      slow=True)
def _(d):
    _scaled(d, 1e18)
    c = _config(d, scenes=[{"name": "s", "source": "s.ply"}, {"name": "far", "source": "far.ply"}],
                output=str(d / "out"))
    return Setup(["run", str(c), "--cache", str(d / "cache")], unchanged=[c])


@case("F4", "numbers", "diagnose a scene × 1e18 (printed 'significance nan%')")
def _(d):
    s = _scaled(d, 1e18)
    return Setup(["diagnose", str(s), "--method", "opacity", "--significance-side", "32", "--n-train", "2"],
                 unchanged=[s], stderr_lacks="nan")


def _moved(d: Path, offset: float, name: str = "moved.ply") -> Path:
    """A random scene of radius ~3 moved ``offset`` along every axis (float32 rounds its centres)."""
    sys.path.insert(0, str(ROOT))
    from harness.core.scene import GaussianScene
    from harness.io.ply import write_ply
    from tests.scene_factory import random_scene

    s = random_scene(300, 0, seed=1)
    write_ply(GaussianScene.from_arrays(s.means + np.float32(offset), s.scales_log, s.quats, s.opacity_logit,
                                        s.sh_dc), d / name)
    return d / name


@case("F10", "numbers", "render a scene of radius 3 moved 1e7 from the origin (centres rounded to a few points)")
def _(d):
    s = _moved(d, 1e7)
    return Setup(["render", str(s), "--longest-side", "32", "--n-test", "2", "--out", str(d / "o")], unchanged=[s],
                 absent=[d / "o"], stderr_has="near the origin")


@case("F11", "numbers", "run: a scene moved 1e7 from the origin beside a good one", want="scene error", slow=True)
def _(d):
    _moved(d, 1e7)
    c = _config(d, scenes=[{"name": "s", "source": "s.ply"}, {"name": "moved", "source": "moved.ply"}],
                output=str(d / "out"))
    return Setup(["run", str(c), "--cache", str(d / "cache")], unchanged=[c], stderr_has="near the origin")


def _tiny_pngs(d: Path, side: int) -> list[str]:
    rng = np.random.default_rng(0)
    a = (rng.random((side, side, 3)) * 255).astype(np.uint8)
    from PIL import Image

    Image.fromarray(a).save(d / "a.png")
    Image.fromarray(255 - a).save(d / "b.png")
    return [str(d / "a.png"), str(d / "b.png")]


@case("F5", "numbers", "compare --metrics mpeg --json of two 4x4 PNGs (IV-SSIM NaN: invalid JSON)")
def _(d):
    return Setup(["compare", *_tiny_pngs(d, 4), "--metrics", "mpeg", "--json"], stderr_lacks="this is a bug")


@case("F6", "numbers", "compare --metrics mpeg of two 4x4 PNGs (printed 'rgb_ivssim nan', exit 0)")
def _(d):
    return Setup(["compare", *_tiny_pngs(d, 4), "--metrics", "mpeg"])


@case("F7", "numbers", "compare --metrics mpeg of two 2x2 PNGs (IndexError)")
def _(d):
    return Setup(["compare", *_tiny_pngs(d, 2), "--metrics", "mpeg", "--json"], stderr_lacks="this is a bug")


@case("F8", "numbers", "compare --json with a plugin metric that returns NaN")
def _(d):
    site = _plugin(d, "nan-metric", "harness.metrics", """
        from harness.metrics import register_metric

        register_metric("nanm", compute=lambda ref, test: float("nan"), higher_is_better=True)
    """)
    a = _png(d / "a.png", 16, 16, 2, 8)
    return Setup(["compare", str(a), str(a), "--metrics", "nanm", "--json"], path=[site], stderr_has="metric nanm")


@case("F9", "numbers", "track a run whose SSIM is NaN on every view of a group (mean taken silently)")
def _(d):
    import pandas as pd

    r = _run_dir(d)
    df = pd.read_parquet(r / "results.parquet")
    df["ssim"] = np.nan
    df2 = pd.concat([df, df.assign(method="random", ssim=0.8)])
    (r / "results.parquet").unlink()
    df2.to_parquet(r / "results.parquet")
    return Setup(["track", str(r), "--baseline", str(d / "b.json"), "--update-baseline", "--no-history"],
                 absent=[d / "b.json"], stderr_has="SSIM")


# ============================================================================ Y: the API's arguments
def _api(d: Path, body: str, *, absent=(), has: str | None = None, want_scene: bool = True) -> Setup:
    """Python code run as a user would: a HarnessError is printed as the CLI prints it (exit 2)."""
    prelude = textwrap.dedent(f"""
        import sys
        import numpy as np
        import harness
        sys.path.insert(0, {str(ROOT)!r})
        from tests.scene_factory import random_scene
        scene = random_scene(200, 0, seed=1)
    """)
    code = prelude + "try:\n" + textwrap.indent(textwrap.dedent(body), "    ") + textwrap.dedent("""
        except harness.HarnessError as err:
            print(f"harness: {err}", file=sys.stderr)
            sys.exit(2)
        print("no error raised", file=sys.stderr)
        sys.exit(0)
    """)
    return Setup([], python=code, absent=[d / a for a in absent], stderr_has=has)


@case("Y1", "api", "harness.prune of a scene with ten NaN opacities (scored about 0.5 and kept)")
def _(d):
    return _api(d, "scene.opacity_logit[:10] = np.nan\nharness.prune(scene, 0.3)", has="opacity")


@case("Y2", "api", "harness.save of a scene with NaN opacities (a .ply that harness.load refuses)")
def _(d):
    return _api(d, f"scene.opacity_logit[:10] = np.nan\nharness.save(scene, {str(d / 'x.ply')!r})",
                absent=["x.ply"], has="opacity")


@case("Y3", "api", "harness.prune(scene, ratio=True) (removed every splat)")
def _(d):
    return _api(d, "harness.prune(scene, True, method='opacity')", has="ratio")


@case("Y4", "api", "harness.cameras of a scene with no splats (bonsai-7k's rig at 1024x768)")
def _(d):
    return _api(d, "harness.cameras(scene.subset(np.zeros(len(scene), bool)))", has="no splats")


@case("Y5", "api", "harness.prune(..., method='random', seed=1.5) (TypeError)")
def _(d):
    return _api(d, "harness.prune(scene, 0.3, method='random', seed=1.5)", has="seed")


@case("Y6", "api", "harness.cameras(scene, seed=-5) (a rig error)")
def _(d):
    return _api(d, "harness.cameras(scene, seed=-5)", has="seed: ")


@case("Y7", "api", "harness.cameras(scene, longest_side='256') (TypeError)")
def _(d):
    return _api(d, "harness.cameras(scene, longest_side='256')", has="longest_side")


@case("Y8", "api", "harness.cameras(scene, longest_side=1.5) (1x1 px cameras)")
def _(d):
    return _api(d, "harness.cameras(scene, longest_side=1.5)", has="longest_side")


@case("Y9", "api", "harness.cameras(scene, n_test=2.5) (TypeError)")
def _(d):
    return _api(d, "harness.cameras(scene, n_test=2.5)", has="n_test")


@case("Y10", "api", "harness.evaluate(config, workers=1.5) (accepted)")
def _(d):
    _config(d)
    return _api(d, f"harness.evaluate({str(d / 'c.yaml')!r}, out={str(d / 'out')!r}, workers=1.5, "
                   f"cache={str(d / 'cache')!r})", absent=["out"], has="workers")


@case("Y11", "api", "harness.prune of a scene whose opacities were cut to half its length (RuntimeError)")
def _(d):
    return _api(d, "scene.opacity_logit = scene.opacity_logit[:100]\nharness.prune(scene, 0.3, method='opacity')",
                has="opacity_logit")


@case("Y12", "api", "harness.prune of a scene whose every opacity is NaN (kept 70 %)")
def _(d):
    return _api(d, "scene.opacity_logit[:] = np.nan\nharness.prune(scene, 0.3)", has="opacity")


@case("Y13", "api", "harness.prune of a scene whose means were replaced by float64 arrays")
def _(d):
    return _api(d, "scene.means = scene.means.astype(np.float64)\nharness.prune(scene, 0.3, method='opacity')",
                has="float32")


@case("Y14", "api", "harness.render with a Camera whose pose is NaN (black image)")
def _(d):
    return _api(d, textwrap.dedent("""
        from harness.core.cameras import Camera
        m = np.eye(4); m[0, 3] = np.nan
        harness.render(scene, Camera(m, 50.0, 50.0, 16.0, 16.0, 32, 32, "nan"))
    """), has="camera")
