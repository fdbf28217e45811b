"""`harness bench study --device DEV CONFIG`: a study run cold on one device — seconds per stage,
images per second, the GPU's memory — and its tables checked against a CPU run of a subset.

Three fresh ``harness run`` subprocesses in this checkout's root (each with its own empty stage
cache: metric entries do not key on the device, so a shared cache would hand the device's numbers to
the CPU run):

1. **the study**: CONFIG (on the scenes of ``--scenes`` only, when given: those at hand on a machine
   that cannot hold them all) with ``protocol.device: DEV`` — wall and CPU seconds of the process tree,
   the runner's wall seconds per stage (``run.json``), the images measured and their rate, and the
   peak memory in use on the GPU while it ran (``nvidia-smi`` polled every 0.2 s, else torch's
   ``mem_get_info``; the whole device, every process, less what was in use before);
2. **the check on DEV** and 3. **the check on the CPU**: the subset of CONFIG on the scenes of
   ``--check`` (default: the config's scene with the fewest splats; method entries keep their
   other restrictions, entries restricted to other scenes are dropped),
   once with ``protocol.device: DEV`` and once with ``cpu``; their tables are compared cell by cell
   as printed: equal, different only in the last printed digit, or different by more (listed). The
   camera-aware baselines train on the device, so their masks — and the cells they feed — may differ
   from the CPU's by more than rounding; the report says which tables hold the differences.

``--check none`` skips 2 and 3. Results: ``<out>/study-<config stem>-<device>.{json,md}``. The goals
of a GPU study (reported, not enforced): ``full.yaml`` on one H100-class GPU with 16 cores ≤ 15 min
wall, ``default.yaml`` ≤ 2 min, the tables equal to the CPU path's in their printed digits.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import tempfile
import threading
import time
from pathlib import Path

#: table files that hold measured times (they differ between any two runs)
RUNTIME_TABLES = ("runtime", "summary")
GOALS = {"full": 15 * 60.0, "default": 2 * 60.0}
RUN = "import sys\nfrom harness.cli import main\nsys.exit(main(sys.argv[1:]))\n"
_NUMBER = re.compile(r"[-+−]?\d+(?:\.(\d+))?")


class GpuMemory:
    """Peak memory in use on the GPU of ``device`` while the ``with`` block runs (MiB, None off CUDA)."""

    def __init__(self, device: str, every: float = 0.2):
        self.device, self.every = device, every
        self.index = int(device.split(":")[1]) if ":" in device else 0
        self.peak = self.before = None
        self._stop = threading.Event()
        self._thread = None
        self._read = None
        if device.startswith("cuda"):
            self._read = self._smi if shutil.which("nvidia-smi") else self._torch

    def _smi(self) -> float | None:
        out = subprocess.run(["nvidia-smi", "--query-gpu=memory.used", "--format=csv,noheader,nounits",
                              f"--id={self.index}"], capture_output=True, text=True, timeout=10)
        return float(out.stdout.split()[0]) if out.returncode == 0 and out.stdout.strip() else None

    def _torch(self) -> float | None:
        import torch

        free, total = torch.cuda.mem_get_info(self.index)
        return (total - free) / 2**20

    def _poll(self) -> None:
        while not self._stop.wait(self.every):
            used = self._read()
            if used is not None:
                self.peak = max(self.peak or 0.0, used)

    def __enter__(self):
        if self._read is not None:
            self.before = self._read()
            self._thread = threading.Thread(target=self._poll, daemon=True)
            self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        if self._thread is not None:
            self._stop.set()
            self._thread.join()

    @property
    def used_mib(self) -> float | None:
        """Peak in use during the block less what was in use before it (None: not measured)."""
        if self.peak is None:
            return None
        return max(self.peak - (self.before or 0.0), 0.0)


def subset(doc: dict, scenes: list[str]) -> dict:
    """The resolved config document ``doc`` on ``scenes`` only (module docstring)."""
    out = dict(doc)
    out["scenes"] = [s for s in doc["scenes"] if (s.get("name") if isinstance(s, dict) else s) in scenes]
    methods = []
    for m in doc.get("methods", []):
        if isinstance(m, dict) and m.get("scenes") is not None:
            keep = [s for s in m["scenes"] if s in scenes]
            if not keep:
                continue
            m = {**m, "scenes": keep}
        methods.append(m)
    out["methods"] = methods
    return out


def _write(doc: dict, device: str, path: Path) -> Path:
    path.write_text(json.dumps({**doc, "protocol": {**doc.get("protocol", {}), "device": device}}, indent=1,
                                allow_nan=False))
    return path  # JSON is YAML: `harness run` reads it


def _study(here: Path, config: Path, folder: Path, workers: int | None, device: str, timeout: float) -> dict:
    """One cold ``harness run`` of ``config`` in ``folder``: seconds, stages, images, GPU memory."""
    from harness.benchmarks._common import run_python

    args = ["run", str(config), "--cache", str(folder / "cache"), "--out", str(folder / "out")]
    args += ["--workers", str(workers)] if workers else []
    with GpuMemory(device) as mem:
        _, wall, cpu = run_python(here, RUN, args, timeout=timeout)
    record = json.loads((folder / "out" / "run.json").read_text())
    images = _images(folder / "out")
    stages = {k: float(v) for k, v in record.get("stage_seconds", {}).items()}
    rm = stages.get("render_metrics") or 0.0
    return {"wall_s": wall, "cpu_s": cpu, "stage_wall_s": stages, "images": images,
            "images_per_s": images / wall if wall else None,
            "render_metrics_images_per_s": images / rm if rm else None,
            "gpu_memory_mib": mem.used_mib, "gpu_memory_peak_mib": mem.peak, "workers": record.get("workers"),
            "executor": record.get("executor")}


def _images(out: Path) -> int:
    import pandas as pd

    df = pd.read_csv(out / "results.csv")
    return int((df["status"] == "ok").sum()) if "status" in df else len(df)


def _cells(path: Path) -> list[list[str]]:
    return [[c.strip() for c in line.strip().strip("|").split("|")]
            for line in path.read_text().splitlines() if line.lstrip().startswith("|")]


def _last_digit(a: str, b: str) -> bool:
    """Do two printed cells differ only by one unit in the last printed digit of their numbers?"""
    na, nb = list(_NUMBER.finditer(a)), list(_NUMBER.finditer(b))
    if len(na) != len(nb) or _NUMBER.sub("#", a) != _NUMBER.sub("#", b):
        return False
    for x, y in zip(na, nb):
        digits = len(x.group(1) or "")
        if digits != len(y.group(1) or ""):
            return False
        vx, vy = (float(m.group(0).replace("−", "-")) for m in (x, y))
        if abs(vx - vy) > 10.0 ** -digits * 1.000001:
            return False
    return True


def compare_tables(a: Path, b: Path) -> dict:
    """Cell-by-cell comparison of the Markdown tables of two runs' ``tables`` folders."""
    names = sorted({p.name for d in (a, b) for p in d.glob("*.md")} - {f"{n}.md" for n in RUNTIME_TABLES}
                   - {p.name for d in (a, b) for p in d.glob("*.md") if p.stem.startswith(RUNTIME_TABLES)})
    out = {"files": len(names), "cells": 0, "equal": 0, "last_digit": 0, "more": 0, "missing": [], "differ": []}
    for name in names:
        pa, pb = a / name, b / name
        if not (pa.is_file() and pb.is_file()):
            out["missing"].append(name)
            continue
        ra, rb = _cells(pa), _cells(pb)
        if len(ra) != len(rb):
            out["missing"].append(f"{name} (rows {len(ra)} vs {len(rb)})")
            continue
        for row_a, row_b in zip(ra, rb):
            for x, y in zip(row_a, row_b):
                out["cells"] += 1
                if x == y:
                    out["equal"] += 1
                elif _last_digit(x, y):
                    out["last_digit"] += 1
                else:
                    out["more"] += 1
                    if len(out["differ"]) < 12:
                        out["differ"].append(f"{name}: {row_a[0] or row_a[1]}: {x!r} vs {y!r}")
    return out


def _check(here: Path, doc: dict, scenes: list[str], device: str, folder: Path, workers, timeout) -> dict:
    sub = subset(doc, scenes)
    runs = {}
    for side, dev in (("device", device), ("cpu", "cpu")):
        f = folder / f"check-{side}"
        f.mkdir()
        runs[side] = _study(here, _write(sub, dev, f / "check.yaml"), f, workers, dev, timeout)
    tables = compare_tables(folder / "check-device" / "out" / "tables", folder / "check-cpu" / "out" / "tables")
    return {"scenes": scenes, **runs, "tables": tables}


def _fmt(v, unit="") -> str:
    if v is None:
        return "–"
    return (f"{v:,.0f}" if abs(v) >= 100 else f"{v:.3g}") + unit


def _device_workers(executor: dict) -> list[str]:
    """The row of a GPU run's device workers and where each stage's tasks ran (none on the CPU)."""
    if not executor.get("device_workers"):
        return []
    where = "; ".join(f"{stage} {t['cpu']} CPU / {t['device']} device" for stage, t in executor["tasks"].items())
    return [f"| device workers (tasks per stage) | {executor['device_workers']} ({where}) |"]


def _markdown(config: str, device: str, res: dict) -> str:
    s = res["study"]
    lines = [f"# harness bench study --device {device} ({config}, {res['device_name']})", "",
             f"Scenes: {', '.join(res['scenes'])}.", "",
             "| quantity | value |", "|---|---|",
             f"| wall s (whole run) | {_fmt(s['wall_s'])} |", f"| CPU-s (process tree) | {_fmt(s['cpu_s'])} |"]
    lines += [f"| stage {k} wall s | {_fmt(v)} |" for k, v in s["stage_wall_s"].items()
              if k not in ("total", "hash_inputs")]  # hashing the inputs is part of load
    lines += [f"| images measured | {s['images']:,} |", f"| images/s (whole run) | {_fmt(s['images_per_s'])} |",
              f"| images/s (render+metrics stage) | {_fmt(s['render_metrics_images_per_s'])} |",
              f"| GPU memory in use, peak over the run's start (MiB) | {_fmt(s['gpu_memory_mib'])} |",
              f"| workers | {s['workers']} |"] + _device_workers(s.get("executor") or {})
    goal = GOALS.get(Path(config).stem)
    if goal is not None:
        met = "met" if s["wall_s"] <= goal else "missed"
        lines += ["", f"Goal on one H100-class GPU with 16 cores: {Path(config).name} ≤ {goal / 60:g} min wall; "
                      f"here {s['wall_s'] / 60:.1f} min on {device} ({met} on this machine)."]
    c = res.get("check")
    if c:
        t = c["tables"]
        ratio = c["cpu"]["wall_s"] / c["device"]["wall_s"] if c["device"]["wall_s"] else None
        lines += ["", f"## Check: the subset on {', '.join(c['scenes'])}, on {device} and on the CPU", "",
                  f"{c['device']['images']:,} images; wall {_fmt(c['device']['wall_s'])} s on {device} vs "
                  f"{_fmt(c['cpu']['wall_s'])} s on the CPU (ratio CPU / {device}: {_fmt(ratio)}, one sitting).", "",
                  f"Tables ({t['files']} files, {t['cells']:,} cells as printed): **{t['equal']:,} equal**, "
                  f"{t['last_digit']:,} differ in the last printed digit, {t['more']:,} differ by more."]
        if t["missing"]:
            lines.append(f"Not compared (absent or of another shape in one run): {', '.join(t['missing'])}.")
        lines += [f"- {d}" for d in t["differ"]]
    lines += ["", "Each run from an empty stage cache; seconds are wall seconds of the `harness run` process "
                  "(stages: the runner's own, run.json); CPU-s: user + system of the process tree."]
    return "\n".join(lines)


def _machine() -> str:
    import os

    name = "CPU only"
    try:
        import torch

        if torch.cuda.is_available():
            name = torch.cuda.get_device_name(0)
    except ImportError:
        pass
    return f"{name}, {os.cpu_count()} cores"


def _smallest(specs) -> str:
    """The name of the scene of ``specs`` with the fewest splats (its file's header; absent ones last)."""
    from harness.run.scene_sizes import splat_count
    from harness.run.sources import resolve_paths
    from harness.run.toolkit import Toolkit

    def size(spec) -> float:
        paths, _ = resolve_paths(spec, Toolkit(), Path.cwd())
        return splat_count(paths[0][1], spec.lod) if paths else float("inf")

    return min(specs, key=size).name


def run_device(args, folder: Path, config: Path) -> int:
    from harness.benchmarks._common import write_result
    from harness.core.devices import check_device
    from harness.core.errors import InputError
    from harness.run.config import load_config
    from harness.run.config.files import read_config_file

    device = check_device(args.device, "--device")
    loaded = load_config(config)  # a bad config: one line, before any run
    doc = read_config_file(config)[0]
    names = [s.get("name") if isinstance(s, dict) else s for s in doc["scenes"]]
    for flag, given in (("--scenes", args.scenes), ("--check", args.check if args.check != "none" else None)):
        bad = [s for s in (given.split(",") if given else []) if s not in names]
        if bad:
            raise InputError(flag, f"no scene {bad[0]!r} in {config.name} (its scenes: {', '.join(names)})")
    if args.scenes:
        doc = subset(doc, args.scenes.split(","))
        names = [n for n in names if n in args.scenes.split(",")]
    specs = [s for s in loaded.scenes if s.name in names]
    scenes = [] if args.check == "none" else (args.check.split(",") if args.check else [_smallest(specs)])
    if [s for s in scenes if s not in names]:
        raise InputError("--check", f"the check's scenes must be among --scenes ({', '.join(names)})")
    here = Path(__file__).resolve().parents[2]
    res: dict = {"config": str(args.config), "device": device, "device_name": _machine(),
                 "scenes": names, "workers": args.workers}
    with tempfile.TemporaryDirectory(prefix="bench-study-device-") as tmp:
        tmp = Path(tmp)
        (tmp / "study").mkdir()
        print(f"bench study: {config.name} on {device} ...", flush=True)
        t0 = time.perf_counter()
        res["study"] = _study(here, _write(doc, device, tmp / "study" / "study.yaml"), tmp / "study",
                              args.workers, device, args.timeout)
        print(f"  {res['study']['images']:,} images in {time.perf_counter() - t0:.1f} s", flush=True)
        if scenes:
            print(f"bench study: check on {', '.join(scenes)}: {device} and cpu ...", flush=True)
            res["check"] = _check(here, doc, scenes, device, tmp, args.workers, args.timeout)
    md = _markdown(str(args.config), device, res)
    path = write_result(f"study-{config.stem}-{device.replace(':', '')}", res, md, out=folder)
    print(md)
    print(f"wrote {path}")
    return 0
