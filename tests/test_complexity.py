"""No function of ``harness/report/`` or ``harness/run/`` above cyclomatic complexity 15 (radon's
McCabe count, as ``radon cc`` prints it: every function and method, its closures included).

A dense function is split into named steps, not excused. :data:`PENDING` would hold a function
being rewritten at the complexity it has (so it can only fall); it is empty, and the test asks for
each line to go once its function is at 15 or below.
"""

from __future__ import annotations

from pathlib import Path

import pytest

radon = pytest.importorskip("radon.complexity", reason="radon is a test dependency: pip install -e '.[test]'")

REPO = Path(__file__).resolve().parent.parent
ROOTS = ("harness/report", "harness/run")
LIMIT = 15
#: (file, function) -> its complexity today, owned by the readers' rewrite; may only fall
PENDING: dict[tuple[str, str], int] = {}


def complexities(path: Path) -> dict[str, int]:
    """``{name: complexity}`` of every function and method (``Class.method``) of a source file."""
    return {b.fullname: b.complexity for b in radon.cc_visit(path.read_text()) if hasattr(b, "is_method")}


def measured() -> dict[tuple[str, str], int]:
    return {(str(p.relative_to(REPO)), name): c for root in ROOTS for p in sorted((REPO / root).rglob("*.py"))
            for name, c in complexities(p).items()}


def test_no_function_above_the_limit():
    found = measured()
    over = {k: c for k, c in found.items() if c > PENDING.get(k, LIMIT)}
    assert not over, "split into named steps: " + ", ".join(f"{f}:{n} ({c})" for (f, n), c in sorted(over.items()))
    done = [k for k, c in PENDING.items() if found.get(k, 0) <= LIMIT]
    assert not done, f"at {LIMIT} or below now (or gone): remove from PENDING: {done}"


def test_the_measure_sees_a_dense_function(tmp_path):
    branches = "".join(f"    if x == {i}:\n        return {i}\n" for i in range(LIMIT))
    (tmp_path / "m.py").write_text(f"def dense(x):\n{branches}    return -1\n\n\nclass C:\n    def m(self):\n"
                                   "        return [i for i in range(3) if i]\n")
    assert complexities(tmp_path / "m.py") == {"dense": LIMIT + 1, "C.m": 3}
