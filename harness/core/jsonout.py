"""JSON the harness prints or writes for others to read: always valid JSON (RFC 8259).

Python's ``json`` writes ``NaN``, ``Infinity`` and ``-Infinity`` for non-finite floats, which no
strict parser accepts. Here every non-finite number — Python or numpy — is written as ``null``
(the documented meaning: "no finite value"; where the infinity itself is meaningful, as an
identical-image PSNR, the command says so with an extra key, e.g. ``psnr_inf: true``). numpy
scalars and arrays become numbers and lists.
"""

from __future__ import annotations

import json
import math
from typing import Any


def finite_or_null(obj: Any) -> Any:
    """A copy of ``obj`` with non-finite floats replaced by None (dicts, lists, tuples, numpy)."""
    try:
        import numpy as np
    except ImportError:  # pragma: no cover
        np = None
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: finite_or_null(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [finite_or_null(v) for v in obj]
    if np is not None:
        if isinstance(obj, np.ndarray):
            return finite_or_null(obj.tolist())
        if isinstance(obj, np.generic):
            return finite_or_null(obj.item())
    return obj


def dumps(obj: Any, **kwargs) -> str:
    """``json.dumps`` of :func:`finite_or_null` ``(obj)``; never emits NaN/Infinity."""
    kwargs.setdefault("default", str)
    return json.dumps(finite_or_null(obj), allow_nan=False, **kwargs)
