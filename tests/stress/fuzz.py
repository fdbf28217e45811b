"""Mutations of real scene files for the reader fuzzer, and one case run through the CLI in-process.

A case is fully determined by (seed file, case number): ``mutate(kind, data, rng)`` returns the
mutated bytes (or, for SOG, the mutated meta.json text and optionally one corrupted image) and a
short description; :func:`run_case` writes it under a work folder and calls
``harness.cli.main(["info", "--json", path])`` with stdout/stderr captured. Outcomes:

* ``loaded``: exit 0;
* ``clean_error``: exit 2 with exactly one stderr line ``harness: ...`` and no traceback;
* ``failure``: anything else (another exit status, an exception escaping ``main``, several lines).
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import re
import shutil
import time
from pathlib import Path

import numpy as np

PLY_TYPES = ["char", "uchar", "short", "ushort", "int", "uint", "float", "double", "int8", "uint8", "float32",
             "float64", "list uchar int", "bogus"]
COUNTS = ["0", "1", "-1", "abc", "", "4294967296", "9223372036854775807", "99999999999999999999999", "1e3"]
FORMATS = ["ascii", "binary_little_endian", "binary_big_endian", "binary_middle_endian", "ascii 2.0", ""]
JSON_VALUES = [None, "x", -1, 0, 1e308, -1e308, [], {}, True, [1, 2], "../missing.webp", 2**40]


def _header_end(data: bytes) -> int:
    i = data.find(b"end_header\n")
    return len(data) if i < 0 else i + len(b"end_header\n")


def _flip(data: bytes, rng, lo: int, hi: int, k: int) -> bytes:
    b = bytearray(data)
    if hi <= lo:
        return bytes(b)
    for pos in rng.integers(lo, hi, k):
        b[pos] = int(rng.integers(0, 256))
    return bytes(b)


def _header_edit(data: bytes, rng) -> tuple[bytes, str]:
    end = _header_end(data)
    lines = data[:end].decode("latin-1").split("\n")
    body = data[end:]
    op = rng.choice(["count", "format", "ptype", "pname", "delete", "duplicate", "junk", "drop_end", "swap"])
    props = [i for i, ln in enumerate(lines) if ln.startswith("property")]
    if op == "count":
        i = next(i for i, ln in enumerate(lines) if ln.startswith("element vertex"))
        n = int(lines[i].split()[2])
        v = rng.choice(COUNTS + [str(n - 1), str(n + 1), str(2 * n), str(n // 2)])
        lines[i] = f"element vertex {v}"
    elif op == "format":
        lines[1] = f"format {rng.choice(FORMATS)} 1.0"
    elif op == "ptype":
        i = int(rng.choice(props))
        lines[i] = f"property {rng.choice(PLY_TYPES)} {lines[i].split()[-1]}"
    elif op == "pname":
        i = int(rng.choice(props))
        lines[i] = " ".join(lines[i].split()[:-1] + [rng.choice(["x", "rot_0", "f_dc_0", "opacity", "q", "f_rest_99"])])
    elif op == "delete":
        del lines[int(rng.choice(props))]
    elif op == "duplicate":
        i = int(rng.choice(props))
        lines.insert(i, lines[i])
    elif op == "junk":
        lines.insert(int(rng.integers(1, len(lines) - 1)),
                     rng.choice(["element face 3", "element face 1\nproperty list uchar int vertex_indices", "bogus",
                                 "property float", "element vertex", "comment \x00\xff", "element extra 2"]))
    elif op == "drop_end":
        lines = [ln for ln in lines if ln != "end_header"]
    else:
        if len(props) > 1:
            i, j = rng.choice(props, 2, replace=False)
            lines[i], lines[j] = lines[j], lines[i]
    return "\n".join(lines).encode("latin-1") + body, f"header:{op}"


def mutate_binary(kind: str, data: bytes, rng) -> tuple[bytes, str]:
    """Mutations of a .ply or .splat file's bytes."""
    hdr = _header_end(data) if kind == "ply" else 0
    ops = ["flip_body", "flip_any", "truncate", "append", "empty", "zero_quat", "nan"]
    if kind == "ply":
        ops += ["header", "header", "header", "flip_header", "truncate_header"]
    op = str(rng.choice(ops))
    if op == "header":
        return _header_edit(data, rng)
    if op == "flip_body":
        return _flip(data, rng, hdr, len(data), int(rng.integers(1, 64))), op
    if op == "flip_any":
        return _flip(data, rng, 0, len(data), int(rng.integers(1, 8))), op
    if op == "flip_header":
        return _flip(data, rng, 0, hdr, int(rng.integers(1, 4))), op
    if op == "truncate":
        return data[: int(rng.integers(0, len(data)))], op
    if op == "truncate_header":
        return data[: int(rng.integers(0, max(hdr, 1)))], op
    if op == "append":
        return data + rng.integers(0, 256, int(rng.integers(1, 100)), dtype=np.uint8).tobytes(), op
    if op == "empty":
        return b"", op
    b = bytearray(data)
    if kind == "splat":  # 32-byte rows: quaternion bytes 28..31 = 128 decode to 0
        rows = (len(b)) // 32
        r = int(rng.integers(0, max(rows, 1)))
        if op == "zero_quat":
            b[r * 32 + 28: r * 32 + 32] = bytes([128] * 4)
        else:  # a NaN position
            b[r * 32: r * 32 + 4] = np.float32(np.nan).tobytes()
        return bytes(b), op
    # ply: overwrite a random float32-aligned word of the body with NaN / inf / zeros
    word = {"zero_quat": b"\x00" * 16, "nan": np.float32(rng.choice([np.nan, np.inf, -np.inf])).tobytes()}[op]
    pos = hdr + 4 * int(rng.integers(0, max((len(b) - hdr) // 4 - 4, 1)))
    b[pos: pos + len(word)] = word
    return bytes(b), op


def _paths(obj, prefix=()):
    yield prefix
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield from _paths(v, prefix + (k,))
    elif isinstance(obj, list):
        for i, v in enumerate(obj[:4]):
            yield from _paths(v, prefix + (i,))


def mutate_sog(meta_text: str, rng) -> tuple[str, str | None, str]:
    """(meta.json text, name of an image file to corrupt or None, description)."""
    op = str(rng.choice(["delete", "retype", "retype", "count", "files", "text_flip", "truncate", "image"]))
    if op == "text_flip":
        b = _flip(meta_text.encode(), rng, 0, len(meta_text), int(rng.integers(1, 6)))
        return b.decode("latin-1"), None, op
    if op == "truncate":
        return meta_text[: int(rng.integers(0, len(meta_text)))], None, op
    meta = json.loads(meta_text)
    if op == "image":
        files = [f for v in meta.values() if isinstance(v, dict) for f in v.get("files", [])]
        return meta_text, str(rng.choice(files)), op
    if op == "count":
        choices = [0, 1, -5, meta["count"] + 1, meta["count"] * 4, 10**12, "12", 3.5]
        meta["count"] = choices[int(rng.integers(0, len(choices)))]
        return json.dumps(meta), None, op
    paths = [p for p in _paths(meta) if p]
    path = paths[int(rng.integers(0, len(paths)))]
    parent = meta
    for k in path[:-1]:
        parent = parent[k]
    if op == "delete":
        del parent[path[-1]]
    elif op == "files":
        key = str(rng.choice([k for k, v in meta.items() if isinstance(v, dict) and "files" in v]))
        choices = [["nope.webp"], [], "x.webp", [1], meta[key]["files"] * 2]
        meta[key]["files"] = choices[int(rng.integers(0, len(choices)))]
    else:
        parent[path[-1]] = JSON_VALUES[int(rng.integers(0, len(JSON_VALUES)))]
    return json.dumps(meta), None, f"{op}:{'/'.join(map(str, path))}" if op != "files" else op


# --------------------------------------------------------------------------- one case
_ONE_LINE = re.compile(r"^harness: [^\n]*\n$")


def call_info(path: Path) -> tuple[int | None, str, str]:
    """(exit status or None when an exception escaped, stderr, exception repr)."""
    from harness.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            rc = main(["info", "--json", str(path)])
            exc = ""
        except (Exception, MemoryError, SystemExit) as e:  # noqa: BLE001 - every escape (timeouts too) is a finding
            rc, exc = None, f"{type(e).__name__}: {e}"[:300]
    return rc, err.getvalue(), exc


def classify(rc, stderr: str, exc: str) -> str:
    if rc == 0:
        return "loaded"
    if rc == 2 and _ONE_LINE.match(stderr) and "Traceback" not in stderr:
        return "clean_error"
    return "failure"


class CaseTimeout(Exception):
    """A case ran longer than the fuzzer's per-case limit (a reader loop that does not end)."""


def _on_alarm(signum, frame):
    raise CaseTimeout("case exceeded the per-case time limit")


def run_cases(seeds: list[dict], start: int, count: int, work: str, mem_limit_gb: float = 6.0,
              case_limit_s: int = 20) -> dict:
    """Run cases ``start .. start+count`` (seed = case % len(seeds)) in this (worker) process, each
    under SIGALRM after ``case_limit_s`` seconds and a ``mem_limit_gb`` address-space limit;
    returns counts, failures (a timeout is a failure) and cases slower than 10 s."""
    import resource
    import signal

    lim = int(mem_limit_gb * 2**30)
    resource.setrlimit(resource.RLIMIT_AS, (lim, lim))
    signal.signal(signal.SIGALRM, _on_alarm)
    work_dir = Path(work) / f"w{os.getpid()}_{start}"
    work_dir.mkdir(parents=True, exist_ok=True)
    counts = {"loaded": 0, "clean_error": 0, "failure": 0}
    failures, slow = [], []
    for case in range(start, start + count):
        seed = seeds[case % len(seeds)]
        rng = np.random.default_rng(case)
        if seed["kind"] == "sog":
            text, bad_image, desc = mutate_sog(seed["meta"], rng)
            folder = work_dir / "sog"
            shutil.rmtree(folder, ignore_errors=True)
            folder.mkdir()
            # the images are hard links to one copy inside the work folder: a symlink leading out of
            # the scene folder is refused by the reader (issue 15: a scene never makes it read outside)
            local = work_dir / f"sog-seed-{Path(seed['dir']).name}"
            if not local.is_dir():
                local.mkdir()
                for f in Path(seed["dir"]).iterdir():
                    if f.name != "meta.json":
                        shutil.copy(f, local / f.name)
            for f in local.iterdir():
                os.link(f, folder / f.name)
            if bad_image:
                (folder / bad_image).unlink(missing_ok=True)
                raw = (Path(seed["dir"]) / bad_image).read_bytes()
                cut = rng.random() < 0.5
                (folder / bad_image).write_bytes(raw[: int(rng.integers(0, len(raw)))] if cut
                                                 else _flip(raw, rng, 0, len(raw), int(rng.integers(1, 20))))
            (folder / "meta.json").write_text(text, encoding="latin-1")
            target = folder / "meta.json"
        else:
            data, desc = mutate_binary(seed["kind"], Path(seed["path"]).read_bytes(), rng)
            target = work_dir / f"case.{seed['kind']}"
            target.write_bytes(data)
        t0 = time.perf_counter()
        signal.alarm(case_limit_s)
        try:
            rc, stderr, exc = call_info(target)
        finally:
            signal.alarm(0)
        dt = time.perf_counter() - t0
        outcome = classify(rc, stderr, exc)
        counts[outcome] += 1
        if dt > 10.0:
            slow.append({"case": case, "seed": seed["name"], "mutation": desc, "seconds": round(dt, 1)})
        if outcome == "failure" and len(failures) < 50:
            failures.append({"case": case, "seed": seed["name"], "mutation": desc, "rc": rc,
                             "stderr": stderr[-400:], "exception": exc})
    shutil.rmtree(work_dir, ignore_errors=True)
    return {"counts": counts, "failures": failures, "slow": slow}
