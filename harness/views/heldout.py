"""The four built-in view protocols (:mod:`harness.views.protocols`), each one registration.

* ``rig``: the scene's own held-out views — those of the rig the camera-aware methods train on
  (they interleave with its training views, :mod:`harness.views.rigs`), or of its camera file or
  MPEG content.
* ``shifted``: the same rig kind with another camera distribution — rings ``rings_above`` degrees
  above the training rig's highest ring, a field of view ``fov_scale`` times as wide (the distance
  fit moves the cameras back accordingly) and other azimuths (seed + ``seed_offset``) — so
  "camera-aware" is not the same as "trained on the test distribution". A config's mapping with a
  name of its own (``{name: steep, rings_above: [40]}``) is a shifted protocol that changes only
  what it names: what it does not give is the training rig's (no rings above, the same field of
  view, the same seed) — :data:`SHIFT_BLANK`.
* ``independent``: random views of :mod:`harness.views.independent`, defined without the training
  rig's path, rings or field of view (and without any virtual rig).
* ``real``: the held-out cameras of the capture a scene carries (all, or the first ``n_test`` by
  name; :mod:`harness.io.capture`), measured against the photos as well as against the unpruned
  render; camera-aware methods train on the capture's training cameras under it.

``shifted`` and ``independent`` apply to scenes whose views come from a synthetic rig; a scene with
a camera file or MPEG content has none of them.
"""

from __future__ import annotations

from dataclasses import dataclass

from harness.core.params import Params, param
from harness.views.protocols import HeldOut, NoViews, ViewRequest, ViewSizes, register_protocol

#: what a shifted protocol named in a config mapping takes for what it does not give (module docstring)
SHIFT_BLANK = {"rings_above": (), "fov_scale": 1.0, "seed_offset": 0}


# --------------------------------------------------------------------------- rig
def own_views(request: ViewRequest, params) -> list:
    """The scene's own held-out views."""
    return request.held_out()


def own_sizes(request: ViewRequest, params) -> ViewSizes:
    return ViewSizes(request.held_out_sizes())


register_protocol("rig", views=own_views, sizes=own_sizes, primary=True, cached=False,
                  notes="held-out views of the rig the camera-aware methods train on")


# --------------------------------------------------------------------------- shifted
@dataclass(frozen=True)
class ShiftedParams(Params):
    rings_above: tuple[float, ...] = param((15.0, 30.0), ge=-80, le=80,
                                           doc="degrees above the training rig's highest ring, one ring each")
    fov_scale: float = param(0.6, ge=0.1, le=2.5, doc="field of view as a multiple of the training rig's")
    seed_offset: int = param(1000, ge=0, doc="added to the run's seed: other azimuths and jitter")


def shifted_views(request: ViewRequest, params: ShiftedParams):
    """The rig kind of the scene with the protocol's camera distribution (module docstring)."""
    from harness.views import rigs

    if not request.synthetic:
        return None
    views = rigs.scene_rig(request.dataset, request.scene(), request.rig_name, n_train=0, n_test=request.n_test,
                           longest_side=request.longest_side, aspect=request.aspect,
                           seed=request.seed + params.seed_offset, fov_deg=rigs.FOV_DEG * params.fov_scale,
                           rings_above=params.rings_above)
    return views.test


def synthetic_sizes(request: ViewRequest, params) -> ViewSizes | None:
    return ViewSizes([request.view_size] * request.n_test) if request.synthetic else None


register_protocol("shifted", views=shifted_views, params=ShiftedParams, sizes=synthetic_sizes,
                  notes="held-out views from another camera distribution (higher rings, narrower field of view, "
                        "other azimuths) than the camera-aware methods' training views")


# --------------------------------------------------------------------------- independent
@dataclass(frozen=True)
class IndependentParams(Params):
    seed_offset: int = param(2000, ge=0, doc="added to the run's seed (and the scene's own): other views")


def independent_views(request: ViewRequest, params: IndependentParams):
    """Random views of :mod:`harness.views.independent` (module docstring)."""
    from harness.views.independent import independent_views as draw

    if not request.synthetic:
        return None
    return draw(request.dataset, request.scene(), request.rig_name, n_test=request.n_test,
                longest_side=request.longest_side, aspect=request.aspect, seed=request.seed + params.seed_offset)


register_protocol("independent", views=independent_views, params=IndependentParams, sizes=synthetic_sizes,
                  notes="random held-out views (positions, look-at jitter, fields of view, close-ups) defined "
                        "independently of the training rig and of any virtual rig")


# --------------------------------------------------------------------------- real
@dataclass(frozen=True)
class RealParams(Params):
    n_test: int | None = param(None, ge=1, doc="the first n_test held-out cameras by name (none: all)")


def _capture(request: ViewRequest):
    """The scene's capture, read and verified (:func:`harness.io.capture.load_capture`); NoViews when
    it carries none or a named one is not on this machine."""
    from harness.io import capture as cap

    cs = request.capture
    if cs is None:
        raise NoViews("it carries no capture (cameras and photos; give `capture:` in the config)")
    if cs.named and cap.capture_root(cs.named) is None:
        raise NoViews(cap.missing_reason(cs.named))
    return cap.load_capture(cs, request.base, digest=request.digest)


def capture_views(request: ViewRequest, params: RealParams) -> HeldOut:
    """The capture's held-out cameras with their photos, and its training cameras, at the run's
    size capped at the photos' (a photo is never upsampled)."""
    from harness.io.capture import protocol_views

    c = _capture(request)
    train, test, side = protocol_views(c, params.n_test, request.longest_side)
    photos = {v.name: (str(c.photos[orig.name]), c.digests[orig.name]) for v, orig in zip(test, c.test)}
    notes = [f"rendered at {side} px (the photos' size), not {request.longest_side} px: a photo is never upsampled"
             ] if side < request.longest_side else []  # (the capture's caveats are the photos table's notes)
    return HeldOut(test, train=train, training_set="capture", photos=photos, source=c.source, notes=notes)


def capture_check(request: ViewRequest, params: RealParams) -> None:
    """A capture that is present but bad is an InputError before any work; an absent named one is not."""
    try:
        _capture(request)
    except NoViews:
        pass


def capture_sizes(request: ViewRequest, params: RealParams) -> ViewSizes | None:
    from harness.io.capture import protocol_views

    try:
        train, test, _ = protocol_views(_capture(request), params.n_test, request.longest_side)
    except NoViews:
        return None
    return ViewSizes([(c.width, c.height) for c in test], [(c.width, c.height) for c in train], photos=True)


register_protocol("real", views=capture_views, params=RealParams, sizes=capture_sizes, check=capture_check,
                  primary=True, cached=False,
                  notes="the real capture's held-out cameras; camera-aware methods train on its training cameras; "
                        "'vs photo' metrics compare with the captured photos, the others with the unpruned render")
