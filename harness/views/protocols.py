"""View protocols: where a run's held-out views come from, each registered once.

    register_protocol("top", views=top_views, params=TopParams, notes="views from straight above the scene")

* ``views(request, params) -> [Camera] | HeldOut | None``: the held-out views of one scene.
  ``request`` (:class:`ViewRequest`) is what the run knows of the scene — its name, the named
  dataset it is, its rig setting and kind, the run's view settings (``n_test``, ``longest_side``,
  ``aspect``, ``seed``), the scene itself and its own held-out views, both computed on first use —
  and ``params`` the protocol's resolved parameters. A list of cameras is measured with the masks
  of the scene's training views; a :class:`HeldOut` may bring a training set of its own (camera-aware
  pruners then score again on it) and a photo per view (each pruned render is then also measured
  against the photo: the ``gt_`` metrics). ``None``: the protocol does not apply to this scene,
  silently; :class:`NoViews`: it does not, and the run says why.
* ``params``: a frozen :class:`~harness.core.params.Params` dataclass; a config names a protocol as a
  word (``protocols: [rig, top]``) or a mapping (``{name: top, n_views: 6}``; a second instance
  under a name of its own: ``{name: top2, protocol: top, n_views: 2}``).
* ``notes``: one sentence, printed after the protocol's name in every table title and on the page.
* ``primary``: may be a run's first protocol, whose views the plots and figures show: its views
  are the held-out views of the scene's own training set (``rig``) or it brings its own (``real``).
* ``cached``: its views depend on nothing but the scene, the run's view settings and the params,
  so the run keeps them in the stage cache (keyed on those and on the code of the views function's
  module); a protocol that reads files of its own (photos) says ``cached=False``.
* ``check(request, params)``: optional; raises :class:`~harness.core.errors.InputError` before any
  work when the protocol cannot measure this scene as configured (a bad capture).
* ``sizes(request, params) -> ViewSizes | None``: optional; the sizes of its views without rendering
  or loading the scene, for ``harness plan --estimate`` (default: ``n_test`` views of the run's view
  size, measured with the scene's training views).

The run names every view ``<protocol>/<camera>`` except the scene's own held-out views, which keep
their names wherever they are measured. Built-ins (:mod:`harness.views.heldout`): ``rig``,
``shifted``, ``independent`` and ``real``; third-party packages add protocols through the
``harness.protocols`` entry-point group (a module whose import calls :func:`register_protocol`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from harness.core.cameras import Camera
from harness.core.params import Params
from harness.core.registry import RegistrationError, Registry

ENTRY_POINT_GROUP = "harness.protocols"
#: the built-in protocol whose views are the scene's own held-out views (the training rig's)
PRIMARY = "rig"


class NoViews(Exception):
    """The protocol does not apply to this scene; the message says why (the run prints it)."""


@dataclass(frozen=True)
class NoParams(Params):
    """Parameters of a protocol that has none."""


@dataclass
class HeldOut:
    """A scene's held-out views under one protocol: ``test`` cameras; ``train``: a training set of the
    protocol's own, named ``training_set`` (None: the scene's training views); ``photos``: view name
    -> (photo file, its sha256); ``source`` and ``notes``: what the views are of, for the run's log."""

    test: list[Camera]
    train: list[Camera] | None = None
    training_set: str = "rig"
    photos: dict[str, tuple[str, str]] = field(default_factory=dict)
    source: str = ""
    notes: list[str] = field(default_factory=list)


@dataclass
class ViewSizes:
    """What ``harness plan --estimate`` counts of a protocol on a scene: the (width, height) of each
    held-out view, of its own training cameras (None: the scene's), and whether the views have photos."""

    test: list[tuple[int, int]]
    train: list[tuple[int, int]] | None = None
    photos: bool = False


@dataclass
class ViewRequest:
    """What the run knows of a scene when it asks a protocol for its views (module docstring).
    ``scene()`` loads the scene, ``held_out()`` computes its own held-out views, each on first call;
    ``synthetic``: those come from a synthetic rig (not a camera file or MPEG content), whose views
    are ``view_size`` (width, height); ``capture``: the capture it carries
    (:class:`harness.io.capture.CaptureSpec`, None: none); ``base``: the folder relative paths are read
    from; ``digest(path)``: a file's content digest (sha256 hex). ``own_sizes()`` stands in for the
    sizes of ``held_out()`` where the views are only counted (``harness plan --estimate``)."""

    name: str
    dataset: str | None
    rig: str
    kind: str
    n_train: int
    n_test: int
    longest_side: int
    aspect: float | None
    seed: int
    scene: Callable[[], Any]
    held_out: Callable[[], list[Camera]]
    synthetic: bool = True
    view_size: tuple[int, int] = (0, 0)
    capture: Any = None
    base: Path = Path(".")
    digest: Callable[[Path], str] | None = None
    own_sizes: Callable[[], list[tuple[int, int]]] | None = None

    def held_out_sizes(self) -> list[tuple[int, int]]:
        """(width, height) of each of the scene's own held-out views."""
        return self.own_sizes() if self.own_sizes is not None else [(c.width, c.height) for c in self.held_out()]

    @property
    def rig_name(self) -> str:
        """The scene's rig as the run builds it: ``default`` for a named dataset (its own), else
        ``forward`` for a scene the config calls forward-facing, else the setting (``auto``...)."""
        from harness.views import rigs

        if self.rig == "default" and self.dataset not in rigs.SCENE_RIGS and self.kind == "forward-facing":
            return "forward"
        return self.rig


@dataclass(frozen=True)
class ProtocolSpec:
    name: str
    views: Callable
    params: type[Params]
    notes: str
    primary: bool = False
    cached: bool = True
    check: Callable | None = None
    sizes: Callable | None = None


@dataclass(frozen=True)
class Protocol:
    """One protocol of a run: its name in the config (``name``: what its rows and tables are called),
    the registration it is an instance of, and its resolved parameters."""

    name: str
    spec: ProtocolSpec
    params: Params

    @property
    def primary(self) -> bool:
        return self.spec.primary

    def key(self) -> dict:
        """What identifies its views beyond the scene and the run's settings (the cache key's part)."""
        return {"name": self.name, "protocol": self.spec.name, **_plain(self.params.to_dict())}

    def views(self, request: ViewRequest) -> HeldOut | None:
        """The held-out views of one scene (module docstring); raises :class:`NoViews`."""
        got = self.spec.views(request, self.params)
        if got is None or isinstance(got, HeldOut):
            return got
        cams = list(got)
        if not all(isinstance(c, Camera) for c in cams):
            raise TypeError(f"protocol {self.spec.name!r}: views() returned {type(got).__name__}, expected a list "
                            "of Camera or a HeldOut")
        return HeldOut(cams)

    def check(self, request: ViewRequest) -> None:
        if self.spec.check is not None:
            self.spec.check(request, self.params)

    def sizes(self, request: ViewRequest) -> ViewSizes | None:
        """Its views' sizes on a scene, for estimates (module docstring)."""
        if self.spec.sizes is not None:
            return self.spec.sizes(request, self.params)
        return ViewSizes([request.view_size] * request.n_test)


def _plain(d: dict) -> dict:
    return {k: list(v) if isinstance(v, tuple) else v for k, v in d.items()}


PROTOCOL_SPECS: Registry[ProtocolSpec] = Registry("view protocol", modules=("harness.views.heldout",),
                                                  group=ENTRY_POINT_GROUP)


def register_protocol(name: str, *, views: Callable, params: type[Params] = NoParams, notes: str = "",
                      primary: bool = False, cached: bool = True, check: Callable | None = None,
                      sizes: Callable | None = None) -> ProtocolSpec:
    """Register view protocol ``name`` (module docstring)."""
    where = f"view protocol {name!r}"
    if not isinstance(name, str) or not name or "/" in name or name != name.strip():
        raise RegistrationError(where, "the name must be a word without '/' (it names views and table files)")
    if not callable(views):
        raise RegistrationError(where, f"views must be a function views(request, params), got {type(views).__name__}")
    if not (isinstance(params, type) and issubclass(params, Params)):
        raise RegistrationError(where, f"params must be a Params dataclass, got {params!r}")
    if not isinstance(notes, str):
        raise RegistrationError(where, f"notes must be text, got {notes!r}")
    for field_name, fn in (("check", check), ("sizes", sizes)):
        if fn is not None and not callable(fn):
            raise RegistrationError(where, f"{field_name} must be a function {field_name}(request, params) or None")
    spec = ProtocolSpec(name, views, params, notes, bool(primary), bool(cached), check, sizes)
    PROTOCOL_SPECS.add(name, spec, same=lambda a, b: (a.views.__module__, a.views.__qualname__, a.params) ==
                       (b.views.__module__, b.views.__qualname__, b.params))
    return spec


def protocol(name: str, kind: str | None = None, values: dict | None = None, *, blank: dict | None = None) -> Protocol:
    """An instance named ``name`` of the registered protocol ``kind`` (default: ``name``), its
    parameters ``values`` over ``blank`` over the registered defaults; ``KeyError`` for an unknown
    protocol, :class:`~harness.core.params.ParamError` for a bad parameter."""
    spec = PROTOCOL_SPECS.get(kind or name)
    return Protocol(name, spec, spec.params.parse({**(blank or {}), **(values or {})}))


def notes(name: str) -> str:
    """The notes of a protocol a run's results name (a plugin's, or ``a named view protocol``)."""
    try:
        return PROTOCOL_SPECS.get(name).notes or "a named view protocol"
    except KeyError:
        return "a named view protocol"


def names() -> list[str]:
    return PROTOCOL_SPECS.names()
