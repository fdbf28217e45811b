"""The view sections of a run config: ``protocols:`` (the registered view protocols,
:mod:`harness.views.protocols`) and a scene's ``capture:``. Every problem is an :class:`InputError`
naming the key path."""

from __future__ import annotations

from harness.core.errors import InputError
from harness.io.capture import CaptureSpec
from harness.run.config.checks import expand_env
from harness.run.config.checks import mapping as _mapping
from harness.run.config.checks import num as _num
from harness.run.config.checks import only as _only
from harness.run.config.checks import string as _str


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
    """``protocols: [rig, shifted, {name: real, n_test: 8}, {name: steep, protocol: shifted, rings_above: [40]}]``:
    each a registered view protocol (:mod:`harness.views.protocols`) named by a word, or a mapping
    with its parameters; ``protocol:`` makes an instance of a registered protocol under a name of its
    own. A mapping naming no registered protocol and giving no ``protocol:`` is a shifted one that
    changes only what it names (:data:`harness.views.heldout.SHIFT_BLANK`). The first must be one that
    may lead a run (``rig``, ``real``)."""
    from harness.views.protocols import PROTOCOL_SPECS

    if not isinstance(v, list) or not v:
        raise InputError(src, "protocols: expected a non-empty list of view protocols (e.g. [rig, shifted])")
    out = tuple(_protocol(e, f"protocols[{i}]", src) for i, e in enumerate(v))
    names = [p.name for p in out]
    if len(set(names)) != len(names):
        raise InputError(src, f"protocols: duplicate names in {names}")
    if not out[0].primary:
        leads = ", ".join(f"`{s.name}`" for s in PROTOCOL_SPECS if s.primary)
        raise InputError(src, f"protocols[0]: the first protocol must be the training rig's own views or one with "
                              f"training views of its own ({leads})")
    return out


def _protocol(e, where: str, src):
    """One entry of ``protocols:`` (:func:`protocols`) as a :class:`harness.views.protocols.Protocol`."""
    from harness.core.params import ParamError
    from harness.core.suggest import unknown
    from harness.views.heldout import SHIFT_BLANK
    from harness.views.protocols import PROTOCOL_SPECS, protocol

    e = {"name": e} if isinstance(e, str) else dict(_mapping(e, where, src))
    name = _str(e.pop("name", None), f"{where}.name", src)
    kind = e.pop("protocol", None)
    blank = SHIFT_BLANK if kind is None and e and name not in PROTOCOL_SPECS else {}
    kind = "shifted" if blank else name if kind is None else _str(kind, f"{where}.protocol", src)
    if kind not in PROTOCOL_SPECS:
        raise InputError(src, f"{where}{'.protocol' if kind != name else ''}: "
                              f"{unknown('view protocol', kind, PROTOCOL_SPECS.names())} (or give a mapping)")
    if "/" in name:
        raise InputError(src, f"{where}.name: {name!r} has a '/' (it names views and table files)")
    try:
        return protocol(name, kind, e, blank=blank)
    except ParamError as err:
        raise InputError(src, f"{where}.{err}" if err.key else f"{where}: {err}") from None
