"""A run's output folder: owned by one run, names mapped to files one to one, everything checked
before the first write (registered into :data:`tests.stress.cases.CASES`): families **O**, **U**, **W**.

* **O**: two ``harness run`` into one folder at once (results of one beside the tables of the
  other, both exit 0), ``harness tables`` into a folder a run is writing, a run killed with
  ``kill -9`` and run again.
* **U**: names that collided as files (scenes ``x/y`` and ``x_y``, variants ``a b`` and ``a_b``, a
  scene named ``..``, scenes ``A`` and ``a``), names refused only at the end or printed raw (300
  characters, an escape sequence) and a TeX label that killed the run at its plots.
* **W**: what was found only after the output folder was made: a scene source that is
  ``/dev/zero`` or a FIFO, a ``--cache`` that is a file, a truncated held-out photo; and
  ``plots: []``, which still drew every plot.

The concurrent cases are Python code that runs the commands and checks the folder; they exit 0
when the folder is as it must be, else print the problem and exit 1.
"""

from __future__ import annotations

import os
import textwrap
from pathlib import Path

from tests.stress.cases import ROOT, Setup, _config, _run, case


def _orchestrate(d: Path, body: str) -> Setup:
    """Python code driving several ``harness`` processes in ``d`` (module docstring)."""
    prelude = textwrap.dedent(f"""
        import json, os, signal, subprocess, sys, time
        from pathlib import Path
        d = Path({str(d)!r})

        def harness(*argv, wait=True):
            p = subprocess.Popen([sys.executable, "-m", "harness", *argv], cwd=d, stdout=subprocess.PIPE,
                                 stderr=subprocess.PIPE, text=True, start_new_session=True)
            if not wait:
                return p
            out, err = p.communicate(timeout=90)
            return p.returncode, out, err

        def started(p, path, timeout=60):
            t0 = time.time()
            while not path.exists() and p.poll() is None and time.time() - t0 < timeout:
                time.sleep(0.05)
            return path.exists()

        def fail(why):
            print(why, file=sys.stderr)
            sys.exit(1)

        def consistent(out):
            import pandas as pd
            run = json.loads((out / "run.json").read_text())
            scenes = set(pd.read_csv(out / "results.csv")["scene"])
            tables = set(pd.read_csv(out / "tables" / "comparison.csv")["scene"]) - {{"all scenes"}}
            page = (out / "report.html").read_text()
            if not tables <= scenes:
                fail(f"tables of scenes {{sorted(tables)}} beside results of {{sorted(scenes)}}")
            if f"harness run {{run['name']}}" not in page:
                fail(f"report.html is not the page of run {{run['name']!r}}")
            if {{f"cfg-{{s}}" for s in scenes}} != {{run["name"]}}:
                fail(f"run.json of {{run['name']!r}} beside results of {{sorted(scenes)}}")
    """)
    return Setup([], python=prelude + textwrap.dedent(body), timeout=150)


def _configs(d: Path, *names: str) -> None:
    """A scene ``<name>.ply`` and a config ``c-<name>.yaml`` (named ``cfg-<name>``) per name, all
    writing ``out``."""
    import json
    import sys

    sys.path.insert(0, str(ROOT))
    from harness.io.ply import write_ply
    from tests.scene_factory import random_scene

    for i, name in enumerate(names):
        write_ply(random_scene(3000, 0, seed=i), d / f"{name}.ply")
        (d / f"c-{name}.yaml").write_text(json.dumps({
            "name": f"cfg-{name}", "output": "out", "ratios": [0.1, 0.3, 0.5],
            "protocol": {"longest_side": 64, "metrics": ["psnr", "ssim"], "n_test": 2, "n_train": 0},
            "scenes": [{"name": name, "source": f"{name}.ply"}], "methods": ["opacity", "random"],
            "tables": ["comparison"], "plots": []}))


# ============================================================================ O: one run owns its folder
@case("O1", "ownership", "two harness run into one folder at once (results of one, tables of the other)",
      want="ok", slow=True)
def _(d):
    _configs(d, "a", "b")
    return _orchestrate(d, """
        first = harness("run", "c-a.yaml", "--cache", "ca", wait=False)
        if not started(first, d / "out"):
            fail("the first run never made its folder")
        rb, _, eb = harness("run", "c-b.yaml", "--cache", "cb")
        ra = first.wait(timeout=120)
        lines = eb.strip().splitlines()
        if rb == 0 and ra == 0:
            fail("both runs into one folder exit 0")
        if ra != 0:
            fail(f"the first run failed: {first.stderr.read().strip().splitlines()[-1:]}")
        if rb != 2 or not lines[-1].startswith("harness: ") or "being written" not in lines[-1]:
            fail(f"the second run: exit {rb}, {lines[-1:]}")
        consistent(d / "out")
    """)


@case("O2", "ownership", "harness tables into a folder that a run is writing", slow=True)
def _(d):
    _configs(d, "a")
    return _orchestrate(d, """
        rc, _, err = harness("run", "c-a.yaml", "--cache", "ca")
        if rc != 0:
            fail(f"the first run failed: {err.strip().splitlines()[-1:]}")
        second = harness("run", "c-a.yaml", "--cache", "ca2", wait=False)
        while second.poll() is None and "harness run" not in (line := second.stderr.readline()):
            pass
        time.sleep(1.0)
        rc, out, err = harness("tables", "out")
        second.wait(timeout=120)
        print(err.strip(), file=sys.stderr)
        sys.exit(rc)
    """)


@case("O3", "ownership", "a run killed with kill -9, then run again into the same folder", want="ok", slow=True)
def _(d):
    _configs(d, "a")
    return _orchestrate(d, """
        p = harness("run", "c-a.yaml", "--cache", "ca", wait=False)
        while p.poll() is None and "harness run" not in p.stderr.readline():
            pass
        time.sleep(2.0)
        os.killpg(p.pid, signal.SIGKILL)
        p.wait()
        rc, _, err = harness("run", "c-a.yaml", "--cache", "ca")
        if rc != 0:
            fail(f"the rerun: exit {rc}, {err.strip().splitlines()[-1:]}")
        consistent(d / "out")
    """)


# ============================================================================ U: names -> files
def _names_run(d: Path, scenes: list[dict], methods=("opacity",), check=None, **over) -> Setup:
    s = _run(d, "--out", str(d / "out"), scenes=scenes, methods=list(methods), **over)
    s.check = check
    return s


def _distinct(d: Path, *paths: str):
    """A check: every ``paths`` (relative to the run folder) exists, and no PNG was written beside
    the run folder's own files."""
    def check() -> str | None:
        out = d / "out"
        missing = [p for p in paths if not (out / p).exists()]
        if missing:
            return f"missing {missing[0]}"
        stray = sorted(p.name for p in out.glob("*.png"))
        return f"images in the run folder itself: {stray[:2]}" if stray else None
    return check


def _two_scene_files(d: Path):
    """Checks that scenes ``x/y`` and ``x_y`` got two image folders and two contact sheets."""
    def check() -> str | None:
        out = d / "out"
        folders = [p for p in (out / "images").iterdir() if p.is_dir()] if (out / "images").is_dir() else []
        sheets = list((out / "contact_sheets").glob("*.png"))
        if len(folders) != 2 or len(sheets) != 2:
            return f"{len(folders)} image folder(s), {len(sheets)} contact sheet(s) for 2 scenes"
        page = (out / "report.html").read_text()
        ids = [line for line in page.split("id='img-")[1:]]
        return "duplicate page ids" if len({i.split("'")[0] for i in ids}) != len(ids) else None
    return check


@case("U1", "names", "scenes named 'x/y' and 'x_y' (one images/ folder, one contact sheet, duplicate page ids)",
      want="ok", slow=True)
def _(d):
    return _names_run(d, [{"name": "x/y", "source": "s.ply"}, {"name": "x_y", "source": "s.ply"}],
                      check=_two_scene_files(d))


@case("U2", "names", "method variants 'a b' and 'a_b' (one render file for both)", want="ok", slow=True)
def _(d):
    methods = [{"name": "opacity", "variant": "a b"}, {"name": "opacity", "variant": "a_b"}]

    def check() -> str | None:
        files = [p.name for p in (d / "out" / "images").rglob("opacity*.png")]
        return None if len(files) == 2 else f"{len(files)} render file(s) for two variants: {files}"
    return _names_run(d, [{"name": "s", "source": "s.ply"}], methods=methods, check=check, tables=["comparison"])


@case("U3", "names", "a scene named '..' (its PNGs written into the run folder itself)", want="ok", slow=True)
def _(d):
    return _names_run(d, [{"name": "..", "source": "s.ply"}], check=_distinct(d, "report.html"))


@case("U4", "names", "scenes named 'A' and 'a' (one file on a case-insensitive file system)")
def _(d):
    s = _names_run(d, [{"name": "A", "source": "s.ply"}, {"name": "a", "source": "s.ply"}])
    s.absent = [d / "out"]
    return s


@case("U5", "names", "a 300-character scene name (\"File name too long\" at the end of the run)")
def _(d):
    s = _names_run(d, [{"name": "n" * 300, "source": "s.ply"}])
    s.absent = [d / "out"]
    return s


@case("U6", "names", "a scene name holding ESC[31m (printed raw to the terminal)")
def _(d):
    s = _names_run(d, [{"name": "red\x1b[31mred", "source": "s.ply"}])
    s.absent = [d / "out"]
    s.stderr_lacks = "\x1b"
    return s


@case("U7", "names", "a TeX scene label '$\\x$' (the run died at its plots after replacing results.csv)",
      want="ok", slow=True)
def _(d):
    return _names_run(d, [{"name": "s", "source": "s.ply", "label": "$\\x$"}], check=_distinct(d, "report.html"),
                      plots=["curves"])


# ============================================================================ W: checked before the first write
def _absent_out(s: Setup, d: Path) -> Setup:
    s.absent = [*s.absent, d / "out"]
    return s


@case("W1", "first write", "run with a scene source that is a symlink to /dev/zero")
def _(d):
    (d / "z.ply").symlink_to("/dev/zero")
    return _absent_out(_run(d, "--out", str(d / "out"), scenes=[{"name": "z", "source": "z.ply"}]), d)


@case("W2", "first write", "run with a scene source that is a FIFO")
def _(d):
    os.mkfifo(d / "f.ply")
    return _absent_out(_run(d, "--out", str(d / "out"), scenes=[{"name": "f", "source": "f.ply"}]), d)


@case("W3", "first write", "run --cache FILE (found after the output folder was made)")
def _(d):
    c = _config(d)
    (d / "afile").write_text("x")
    return Setup(["run", str(c), "--cache", str(d / "afile"), "--out", str(d / "out")], unchanged=[d / "afile"],
                 absent=[d / "out"])


@case("W4", "first write", "run on a capture whose held-out photo is truncated (found at render time)")
def _(d):
    import sys

    sys.path.insert(0, str(ROOT))
    from tests.test_capture import write_capture

    cap = write_capture(d / "cap")
    photo = d / "cap" / "photos" / "img2.png"
    photo.write_bytes(photo.read_bytes()[:60])
    return _absent_out(_run(d, "--out", str(d / "out"), protocols=["real"],
                            scenes=[{"name": "s", "source": "s.ply", "capture": cap}]), d)


@case("W5", "first write", "a config with plots: [] (drew every plot)", want="ok", slow=True)
def _(d):
    s = _run(d, "--out", str(d / "out"), plots=[])

    def check() -> str | None:
        drawn = sorted(p.name for p in (d / "out" / "plots").glob("*.png")) if (d / "out" / "plots").exists() else []
        return f"plots drawn: {drawn[:3]}" if drawn else None
    s.check = check
    return s
