"""Bounded memory and plain messages (registered into :data:`tests.stress.cases.CASES`), family M:

* **.sog bundles** whose members inflate past what their textures or JSON may take (a 0.5 MB
  bundle with a 500 MiB member; a 100 MiB ``meta.json``), under a 1 GiB address-space limit;
* **compare** of two 8192x8192 PNGs (PSNR alone needed 6.3 GB);
* **Pillow's warnings and wording**: a 10000 px frame header printed two ``DecompressionBombWarning``
  lines before its error (run here with ``PYTHONWARNINGS=default``); a 0x0 PNG was
  "cannot identify image file <_io.BytesIO …>";
* **writers**: one splat at x = 1e30 moved 99 others in ``.compressed.ply`` silently (now a
  warning); ``spz_version='4'`` from Python said "cannot be written (choose 2, 3, 4)".
"""

from __future__ import annotations

import json
import sys
import zipfile
from pathlib import Path

import numpy as np

from tests.stress.cases import ROOT, Setup, _ply, _png, _sog, case


def _bundle(d: Path, replace: dict[str, bytes]) -> Path:
    """A deflated ``.sog`` of a small valid SOG set with some members replaced."""
    folder = _sog(d, n=20)
    out = d / "s.sog"
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as z:
        for f in sorted(folder.iterdir()):
            z.writestr(f.name, replace.get(f.name, f.read_bytes()))
    return out


@case("M1", "memory", "info of a 0.5 MB .sog whose quats.webp inflates to 500 MiB (1 GiB address space)")
def _(d):
    quats = (_sog(d, n=20, name="q") / "quats.webp").read_bytes()
    s = _bundle(d, {"quats.webp": quats + bytes(500 << 20)})
    return Setup(["info", str(s)], unchanged=[s], mem_limit=1 << 30, stderr_lacks="out of memory")


@case("M2", "memory", "info of a .sog whose meta.json member is 100 MiB (JSON cap 64 MiB)")
def _(d):
    meta = (_sog(d, n=20, name="q") / "meta.json").read_bytes()
    s = _bundle(d, {"meta.json": meta + b" " * (100 << 20)})
    return Setup(["info", str(s)], unchanged=[s])


@case("M3", "memory", "compare two 8192x8192 PNGs --metrics psnr")
def _(d):
    a = _png(d / "a.png", 8192, 8192, 2, 8)
    b = _png(d / "b.png", 8192, 8192, 2, 8)
    return Setup(["compare", str(a), str(b), "--metrics", "psnr"], unchanged=[a, b], stderr_lacks="out of memory")


@case("M4", "messages", "render: a transforms.json frame whose header claims 10000x10000 (warnings shown)")
def _(d):
    from tests.stress.cases_issue24 import _bomb_png  # imported here: that module imports the case table

    s = _ply(d, 50)
    _bomb_png(d / "a.png", 10000, 10000)
    t = d / "transforms.json"
    t.write_text(json.dumps({"camera_angle_x": 0.8, "frames": [{"file_path": "a.png",
                                                                 "transform_matrix": np.eye(4).tolist()}]}))
    return Setup(["render", str(s), "--cameras", str(t), "--out", str(d / "o")], absent=[d / "o"],
                 env={"PYTHONWARNINGS": "default"})


@case("M5", "messages", "compare of a 0x0 PNG: the file and the problem named, no <_io.BytesIO>")
def _(d):
    z = _png(d / "z.png", 0, 0, 2, 8)
    return Setup(["compare", str(z), str(z)], unchanged=[z], stderr_has="z.png: image is empty",
                 stderr_lacks="BytesIO")


@case("M6", "messages", "convert: one splat at x = 1e30 among 100 -> .compressed.ply (warned)", want="ok")
def _(d):
    sys.path.insert(0, str(ROOT))
    from harness.io.ply import write_ply
    from tests.scene_factory import random_scene

    scene = random_scene(100, 0, seed=1)
    scene.means[0] = (1e30, 0.0, 0.0)
    s = d / "far.ply"
    write_ply(scene, s)
    return Setup(["convert", str(s), str(d / "far.compressed.ply")], unchanged=[s],
                 stderr_has="splats are stored up to")


@case("M7", "messages", "Python: harness.save(scene, 'x.spz', spz_version='4')")
def _(d):
    s = _ply(d, 50)
    code = ("import sys, harness\n"
            "try:\n"
            f"    harness.save({str(s)!r}, {str(d / 'x.spz')!r}, spz_version='4')\n"
            "except harness.HarnessError as err:\n"
            "    print(f'harness: {err}', file=sys.stderr)\n"
            "    sys.exit(2)\n")
    return Setup([], python=code, unchanged=[s], absent=[d / "x.spz"], stderr_has="must be an integer")
