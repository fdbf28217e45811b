"""The held-out views of a scene under each view protocol of a run (:mod:`harness.views.protocols`).

The run asks each protocol with one :class:`~harness.views.protocols.ViewRequest` per scene — the
scene loaded only if a protocol looks at it, its own held-out views as the run's ``views`` stage
made them — and

* names every view ``<protocol>/<camera>``, but for the scene's own held-out views, which keep
  their names wherever they are measured (the photos of a view follow its name);
* keeps the views of a ``cached`` protocol in the ``views`` stage, keyed on the scene's digest, the
  config values that declare ``protocol_views`` (:mod:`harness.run.config.keys`), its name and
  dataset, its own held-out views, the protocol's parameters and the code the protocol's views
  function runs (:meth:`harness.run.cache.versions.Versions.protocol`);
* hears why a protocol does not apply to a scene (:class:`~harness.views.protocols.NoViews`).

:func:`check_protocols` asks every protocol's ``check`` for every scene before any output is
written (a bad capture: one line, exit status 2).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from harness.core.cameras import Camera
from harness.run.cache import StageCache, digest_json
from harness.run.config import RunConfig, SceneSpec
from harness.run.toolkit import Toolkit
from harness.views.protocols import HeldOut, NoViews, Protocol, ViewRequest


def capture_spec(spec: SceneSpec, toolkit: Toolkit):
    """The capture a scene carries: its config's, else a named scene's own (``capture: false``: none)."""
    from harness.io.capture import named_spec

    if spec.capture is False or spec.sequence is not None:
        return None
    if spec.capture is not None:
        return spec.capture
    return named_spec(spec.source) if spec.source and toolkit.resolve_dataset(spec.source) else None


def dataset_of(spec: SceneSpec, toolkit: Toolkit) -> str | None:
    """The named dataset a scene is (None: a file of its own)."""
    return spec.source if spec.source and toolkit.resolve_dataset(spec.source) else None


def request(spec: SceneSpec, config: RunConfig, toolkit: Toolkit, base: Path, *, scene=None, held_out=None,
            digest=None, own_sizes=None) -> ViewRequest:
    """What the run tells a protocol about a scene (:class:`ViewRequest`); ``scene`` and ``held_out``
    (callables) are refused when not given: a protocol asked before the scene is read may not use them."""
    from harness.views import rigs

    p, dataset = config.protocol, dataset_of(spec, toolkit)

    def unavailable():
        raise NoViews("the scene is not read at this point")

    aspect = p.aspect
    if aspect is None and spec.rig == "default" and dataset in rigs.SCENE_RIGS:
        aspect = rigs.SCENE_RIGS[dataset].aspect
    return ViewRequest(spec.name, dataset, spec.rig, spec.kind, spec.n_train, spec.n_test, p.longest_side, p.aspect,
                       p.seed, scene or unavailable, held_out or unavailable,
                       synthetic=spec.cameras is None and spec.sequence is None,
                       view_size=rigs.image_size(p.longest_side, aspect or rigs.ASPECT),
                       capture=capture_spec(spec, toolkit), base=base, digest=digest, own_sizes=own_sizes)


def check_protocols(config: RunConfig, base: Path, toolkit: Toolkit | None = None) -> None:
    """Every protocol's ``check`` on every scene, before any output is written."""
    toolkit = toolkit or Toolkit()
    for proto in (p for p in config.protocols if p.spec.check is not None):
        for spec in config.scenes:
            proto.check(request(spec, config, toolkit, base))


def held_out(proto: Protocol, req: ViewRequest, cache: StageCache, code: str, scene_digest: str, inputs: dict
             ) -> tuple[HeldOut | None, str | None]:
    """(the scene's views under ``proto``, None) or (None, why not; None when silently not);
    ``inputs``: what the config puts in the key of cached views
    (:func:`harness.run.config.keys.key_inputs` of ``protocol_views``)."""
    try:
        if not proto.spec.cached:
            got = proto.views(req)
        else:
            got = _cached(proto, req, cache, code, scene_digest, inputs)
    except NoViews as why:
        return None, str(why)
    if got is None or not got.test:
        return None, None
    return _named(proto.name, got, req.held_out()), None


def _cached(proto: Protocol, req: ViewRequest, cache: StageCache, code: str, scene_digest: str,
            inputs: dict) -> HeldOut | None:
    own = digest_json([c.to_dict() for c in req.held_out()])
    source = {**inputs["source"], "scene": scene_digest, "held_out": own, "protocol": proto.key(),
              "name": req.name, "dataset": req.dataset, "synthetic": req.synthetic}
    key = cache.key("views", code=code, **{**inputs, "source": source})
    hit = cache.get_json("views", key)
    if hit is not None and "held_out" in hit:
        return None if hit["held_out"] is None else _from_json(hit["held_out"])
    got = proto.views(req)
    cache.put_json("views", key, {"rig": proto.name, "held_out": None if got is None else _to_json(got)})
    return got


def _to_json(h: HeldOut) -> dict:
    return {"test": [c.to_dict() for c in h.test], "train": None if h.train is None else [c.to_dict() for c in h.train],
            "training_set": h.training_set, "photos": {k: list(v) for k, v in h.photos.items()}, "source": h.source,
            "notes": list(h.notes)}


def _from_json(d: dict) -> HeldOut:
    return HeldOut([Camera.from_dict(c) for c in d["test"]],
                   None if d["train"] is None else [Camera.from_dict(c) for c in d["train"]], d["training_set"],
                   {k: tuple(v) for k, v in d["photos"].items()}, d["source"], list(d["notes"]))


def _named(protocol: str, h: HeldOut, own: list[Camera]) -> HeldOut:
    """``h`` with its views named ``<protocol>/<camera>`` (the scene's own held-out views keep theirs)."""
    mine = {c.name: c.to_dict() for c in own}
    rename = {c.name: c.name if mine.get(c.name) == c.to_dict() else f"{protocol}/{c.name}" for c in h.test}
    return replace(h, test=[replace(c, name=rename[c.name]) for c in h.test],
                   photos={rename.get(k, k): v for k, v in h.photos.items()})
