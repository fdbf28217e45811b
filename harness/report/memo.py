"""A run folder's tables and plots are rebuilt only when what makes them changed.

:func:`harness.report.outputs.publish` writes ``tables/`` and ``plots/`` from the results, the
options (tables, plots, reference, anchor) and the code that builds them; a cached rerun of a study
has the same three, so rebuilding them (19 of the ~20 s such a rerun of the default study took) is
wasted. :func:`inputs_digest` is the sha256 of

* the results: every row and column of the frame (``pandas.util.hash_pandas_object``), its column
  names and dtypes;
* the options, as JSON;
* the code: every project module :mod:`harness.report.outputs` imports, directly or through others
  (read from the source, :func:`harness.core.sources.project_closure`), the modules of every
  registered pruner (their labels and groups name the rows), table, plot and metric (a plugin's
  own), and the versions of Python, numpy, pandas and matplotlib.

After a build, ``<run>/.outputs/memo.json`` keeps that digest, the sha256 of every file written and
the tables themselves (frames as JSON: index, columns, dtypes and values; a table that does not
come back equal to itself is not kept, and the memo is not written). :func:`load` returns them only
when the digest is the same and every file is still there with its bytes; the page is then drawn
from the kept tables (it also shows the run records, which change with every run, so it is always
redrawn). Anything else — no memo, another digest, a file edited or removed, a memo that cannot be
read — rebuilds everything, as without a memo. The memo holds data only (JSON): a folder from
elsewhere cannot make this code run anything.
"""

from __future__ import annotations

import hashlib
import json
import platform
from pathlib import Path

import numpy as np
import pandas as pd

from harness.report.tabledata import Built, Missing, Table, Written

FOLDER = ".outputs"
NAME = "memo.json"
VERSION = 2
#: a memo larger than this is not read (the default study's is well under it)
MAX_BYTES = 256 << 20


def _sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def code_files() -> list[Path]:
    """The source files whose change makes a run's tables and plots stale (module docstring)."""
    from harness.core.sources import module_file, project_closure
    from harness.metrics.registry import METRICS
    from harness.report.plots import PLOT_SPECS
    from harness.report.tables import TABLE_SPECS
    from methods.registry import list_pruners

    names = set(project_closure("harness.report.outputs"))
    fns = [s.fn for s in list_pruners()] + [TABLE_SPECS.get(n).build for n in TABLE_SPECS.names()]
    fns += [PLOT_SPECS.get(n).draw for n in PLOT_SPECS.names()] + [m.compute for m in METRICS]
    names |= {f.__module__ for f in fns if getattr(f, "__module__", None)}
    files = {module_file(n) for n in names}
    return sorted(f for f in files if f is not None and f.suffix == ".py" and f.is_file())


def inputs_digest(df: pd.DataFrame, options: dict) -> str:
    """sha256 of the results, the options and the code that make the tables and plots."""
    import matplotlib

    h = hashlib.sha256()
    h.update(pd.util.hash_pandas_object(df, index=True).to_numpy().tobytes())
    h.update(json.dumps([list(map(str, df.columns)), [str(t) for t in df.dtypes]], allow_nan=False).encode())
    h.update(json.dumps(options, sort_keys=True, default=str, allow_nan=False).encode())
    versions = [platform.python_version(), np.__version__, pd.__version__, matplotlib.__version__]
    h.update(json.dumps(versions, allow_nan=False).encode())
    for f in code_files():
        h.update(f"{f.name}:{_sha(f.read_bytes())}".encode())
    return h.hexdigest()


# --------------------------------------------------------------------------- frames as JSON
def _index(ix: pd.Index) -> dict:
    values = [list(v) for v in ix] if isinstance(ix, pd.MultiIndex) else list(ix)
    return {"multi": isinstance(ix, pd.MultiIndex), "names": list(ix.names), "values": values,
            "dtype": None if isinstance(ix, pd.MultiIndex) else str(ix.dtype)}


def _from_index(d: dict) -> pd.Index:
    if d["multi"]:
        return pd.MultiIndex.from_tuples([tuple(v) for v in d["values"]], names=d["names"])
    return pd.Index(d["values"], name=d["names"][0], dtype=d["dtype"])


def _cell(v):
    """A JSON value for a cell: numbers as they are (NaN and ±inf included), missing as None."""
    if v is None or v is pd.NA or v is pd.NaT:
        return None
    if isinstance(v, (np.integer, np.floating, np.bool_)):
        v = v.item()
    if isinstance(v, float) and not np.isfinite(v):  # strict JSON has no NaN or ±inf: a tagged string
        return {"float": repr(v)}
    return v


def _uncell(v):
    """:func:`_cell` back: a tagged non-finite float to its float."""
    return float(v["float"]) if isinstance(v, dict) and set(v) == {"float"} else v


def frame_to_json(df: pd.DataFrame) -> dict:
    return {"index": _index(df.index), "columns": _index(df.columns), "dtypes": [str(t) for t in df.dtypes],
            "data": [[_cell(v) for v in df.iloc[:, j].tolist()] for j in range(df.shape[1])]}


def frame_from_json(d: dict) -> pd.DataFrame:
    columns, index = _from_index(d["columns"]), _from_index(d["index"])
    # each column a Series of its stored dtype: a frame built from bare arrays re-infers an object
    # column of strings as pandas' string dtype, which no longer equals the table it came from
    data = {j: pd.Series(pd.array([_uncell(v) for v in values], dtype=dtype), index=index, dtype=dtype)
            for j, (values, dtype) in enumerate(zip(d["data"], d["dtypes"]))}
    out = pd.DataFrame(data, index=index)
    out.columns = columns
    return out


def table_to_json(b: Built) -> dict:
    head = {"key": b.key, "name": b.name, "protocol": b.protocol, "title": b.title}
    t = b.table
    if isinstance(t, Missing):
        return {**head, "missing": t.reason}
    return {**head, "disp": frame_to_json(t.disp), "tidy": frame_to_json(t.tidy), "notes": list(t.notes),
            "sections": [[title, frame_to_json(f)] for title, f in t.sections], "warnings": list(t.warnings),
            "caption": t.caption, "heading": t.heading}


def table_from_json(d: dict) -> Built:
    if "missing" in d:
        table = Missing(d["missing"])
    else:
        table = Table(frame_from_json(d["disp"]), list(d["notes"]), frame_from_json(d["tidy"]),
                      [(title, frame_from_json(f)) for title, f in d["sections"]], list(d["warnings"]),
                      d["caption"], d["heading"])
    return Built(d["key"], d["name"], d["protocol"], d["title"], table)


def _same_frame(a: pd.DataFrame, b: pd.DataFrame) -> bool:
    try:
        pd.testing.assert_frame_equal(a, b, check_exact=True)
    except AssertionError:
        return False
    return True


def _same(a: Built, b: Built) -> bool:
    if (a.key, a.name, a.protocol, a.title) != (b.key, b.name, b.protocol, b.title):
        return False
    if isinstance(a.table, Missing) or isinstance(b.table, Missing):
        return a.table == b.table
    x, y = a.table, b.table
    return ((x.notes, x.warnings, x.caption, x.heading) == (y.notes, y.warnings, y.caption, y.heading)
            and _same_frame(x.disp, y.disp) and _same_frame(x.tidy, y.tidy)
            and [t for t, _ in x.sections] == [t for t, _ in y.sections]
            and all(_same_frame(f, g) for (_, f), (_, g) in zip(x.sections, y.sections)))


# --------------------------------------------------------------------------- the memo
def save(run_dir: Path, digest: str, written: Written, plots: Written) -> bool:
    """Keep ``written`` (tables and plots) under ``digest``; False (and no memo) when a table would
    not come back equal to itself, or the memo cannot be written."""
    from harness.io.files import atomic_write_text

    run_dir = Path(run_dir)
    tables = {k: table_to_json(b) for k, b in written.built.items()}
    try:  # strict JSON; a non-finite number left in an index or a note: no memo (rebuilt next time)
        text = json.dumps({"version": VERSION, "digest": digest,
                           "files": {str(Path(p).relative_to(run_dir)): _sha(Path(p).read_bytes())
                                     for p in written.paths},
                           "plots": [str(Path(p).relative_to(run_dir)) for p in plots.paths],
                           "missing": written.missing, "warnings": written.warnings, "notes": written.notes,
                           "tables": tables}, allow_nan=False)
    except ValueError:
        forget(run_dir)
        return False
    back = json.loads(text)["tables"]
    if not all(_same(b, table_from_json(back[k])) for k, b in written.built.items()):
        forget(run_dir)
        return False
    try:
        (run_dir / FOLDER).mkdir(exist_ok=True)
        atomic_write_text(run_dir / FOLDER / NAME, text)
    except OSError:
        return False
    return True


def load(run_dir: Path, digest: str) -> tuple[Written, Written] | None:
    """(tables and plots as written, the plots alone) kept under ``digest``, when every file they
    wrote is still there with its bytes; else None."""
    run_dir = Path(run_dir)
    path = run_dir / FOLDER / NAME
    try:
        if not path.is_file() or path.stat().st_size > MAX_BYTES:
            return None
        memo = json.loads(path.read_text())
        if not isinstance(memo, dict) or memo.get("version") != VERSION or memo.get("digest") != digest:
            return None
        for rel, sha in memo["files"].items():
            f = run_dir / rel
            if ".." in Path(rel).parts or not f.is_file() or _sha(f.read_bytes()) != sha:
                return None
        built = {k: table_from_json(d) for k, d in memo["tables"].items()}
        plots = Written([run_dir / p for p in memo["plots"]])
        paths = [run_dir / rel for rel in memo["files"]]
        return Written(paths, list(memo["missing"]), list(memo["warnings"]), built, list(memo["notes"])), plots
    except (OSError, ValueError, KeyError, TypeError, AttributeError):  # unreadable or not ours: rebuild
        return None


def forget(run_dir: Path) -> None:
    """Remove the memo (its outputs are being replaced)."""
    try:
        (Path(run_dir) / FOLDER / NAME).unlink(missing_ok=True)
    except OSError:
        pass
