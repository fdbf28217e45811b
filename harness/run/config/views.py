"""The view sections of a run config: ``protocols:`` (harness.views.rigs.ViewProtocol, or the
captured views, harness.io.capture.CaptureProtocol) and a scene's ``capture:``. Every problem is an
:class:`InputError` naming the key path."""

from __future__ import annotations

from harness.core.errors import InputError
from harness.io.capture import CaptureProtocol, CaptureSpec
from harness.run.config.checks import expand_env
from harness.run.config.checks import mapping as _mapping
from harness.run.config.checks import num as _num
from harness.run.config.checks import only as _only
from harness.run.config.checks import string as _str
from harness.views import rigs


def capture(d, where, src):
    """``capture: {cameras, images, split | test | test_every, transform}`` or ``capture: false``."""
    if d is False:
        return False
    d = _mapping(d, where, src)
    _only(d, {"cameras", "images", "split", "test", "test_every", "transform"}, where, src)
    for k in ("cameras", "images"):
        if k not in d:
            raise InputError(src, f"{where}.{k}: required (the capture's camera file and photo folder)")
    test = d.get("test", [])
    if not isinstance(test, list) or not all(isinstance(t, str) for t in test):
        raise InputError(src, f"{where}.test: expected a list of view names")
    every = _num(d.get("test_every", 0), f"{where}.test_every", src, lo=0, integer=True)
    given = [k for k in ("split", "test", "test_every") if d.get(k)]
    if len(given) != 1:
        raise InputError(
            src,
            f"{where}: give the held-out views once: `split: FILE`, `test: [names]` or `test_every: k`"
            + (f" (got {', '.join(given)})" if given else ""),
        )
    opt = lambda k: expand_env(_str(d[k], f"{where}.{k}", src)) if k in d else None  # noqa: E731
    return CaptureSpec(cameras=opt("cameras"), images=opt("images"), split=opt("split"), test=tuple(test),
                       test_every=every, transform=opt("transform"))


def protocols(v, src) -> tuple:
    """``protocols: [rig, shifted, {name: steep, rings_above: [20, 40], fov_scale: 0.5, seed_offset: 7},
    real]`` — ``real`` (or ``{name: real, n_test: 8}``: the first 8 by name) is the captured held-out
    views of the scenes that carry a capture (:class:`harness.io.capture.CaptureProtocol`)."""
    if not isinstance(v, list) or not v:
        raise InputError(src, "protocols: expected a non-empty list of view protocols (e.g. [rig, shifted])")
    out = []
    known = [*rigs.PROTOCOLS, "real"]
    for i, e in enumerate(v):
        where = f"protocols[{i}]"
        if e == "real" or (isinstance(e, dict) and e.get("name") == "real"):
            e = _mapping({} if e == "real" else e, where, src)
            _only(e, {"name", "n_test"}, where, src)
            n = e.get("n_test")
            out.append(CaptureProtocol("real", None if n is None else _num(n, f"{where}.n_test", src, lo=1,
                                                                                integer=True)))
            continue
        if isinstance(e, str):
            from harness.core.suggest import unknown

            out.append(rigs.PROTOCOLS.get(e) or _fail(src, f"{where}: {unknown('view protocol', e, known)} "
                                                           "(or give a mapping)"))
            continue
        e = _mapping(e, where, src)
        _only(e, {"name", "rings_above", "fov_scale", "seed_offset"}, where, src)
        above = e.get("rings_above", [])
        if not isinstance(above, list):
            raise InputError(src, f"{where}.rings_above: expected a list of degrees")
        out.append(rigs.ViewProtocol(
            _str(e.get("name"), f"{where}.name", src),
            tuple(float(_num(a, f"{where}.rings_above[{j}]", src, lo=-80, hi=80)) for j, a in enumerate(above)),
            float(_num(e.get("fov_scale", 1.0), f"{where}.fov_scale", src, lo=0.1, hi=2.5)),
            _num(e.get("seed_offset", 0), f"{where}.seed_offset", src, lo=0, integer=True)))
    names = [p.name for p in out]
    if len(set(names)) != len(names):
        raise InputError(src, f"protocols: duplicate names in {names}")
    if out[0].shifted:
        raise InputError(src, "protocols[0]: the first protocol must be the training rig's own views (`rig`) "
                              "or the captured views (`real`)")
    return tuple(out)


def _fail(src, problem):
    raise InputError(src, problem)
