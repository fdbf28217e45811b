"""The ``real`` protocol's views of a scene: its capture (:mod:`harness.io.capture`) read, verified
and sized for a run — held-out cameras with their photos, and the training cameras camera-aware
pruners use under it."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from harness.core.cameras import Camera
from harness.io.capture import CaptureProtocol
from harness.run.cache import StageCache
from harness.run.config import RunConfig, SceneSpec
from harness.run.toolkit import Toolkit


@dataclass
class RealViews:
    """The ``real`` protocol's cameras of one scene, at the run's render size (capped at the photos')."""

    protocol: str
    train: list[Camera]
    test: list[Camera]                      # named ``<protocol>/<camera>``
    photos: dict[str, tuple[str, str]]      # view name -> (photo path, sha256)
    source: str
    notes: list[str] = field(default_factory=list)
    side: int = 0


def check_captures(config: RunConfig, base: Path, toolkit: Toolkit | None = None) -> None:
    """Read and verify every capture the run's ``real`` protocol will measure, before any output is
    written: a bad one is an :class:`InputError` (exit status 2); an absent named one is not."""
    from harness.io import capture as cap

    if any(isinstance(p, CaptureProtocol) for p in config.protocols):
        for spec in config.scenes:
            cs = capture_spec(spec, toolkit or Toolkit())
            if cs is not None and not (cs.named and cap.capture_root(cs.named) is None):
                cap.load_capture(cs, base)


def capture_spec(spec: SceneSpec, toolkit: Toolkit):
    """The capture a scene carries: its config's, else a named scene's own (``capture: false``: none)."""
    from harness.io.capture import named_spec

    if spec.capture is False or spec.sequence is not None:
        return None
    if spec.capture is not None:
        return spec.capture
    return named_spec(spec.source) if spec.source and toolkit.resolve_dataset(spec.source) else None


def capture_views(spec: SceneSpec, protocol: CaptureProtocol | None, config: RunConfig, cache: StageCache,
                  toolkit: Toolkit, base: Path) -> tuple[RealViews | None, str | None]:
    """(the ``real`` protocol's views of a scene, None) or (None, why it has none). A capture that
    is present but bad raises :class:`InputError`; an absent named capture is a reason, not an error."""
    from harness.io import capture as cap

    if protocol is None:
        return None, None
    cs = capture_spec(spec, toolkit)
    if cs is None:
        return None, "it carries no capture (cameras and photos; give `capture:` in the config)"
    if cs.named and cap.capture_root(cs.named) is None:
        return None, cap.missing_reason(cs.named)
    c = cap.load_capture(cs, base, digest=cache.files.digest)
    train, test, side = cap.protocol_views(c, protocol, config.protocol.longest_side)
    photos = {v.name: (str(c.photos[orig.name]), c.digests[orig.name])
              for v, orig in zip(test, c.test)}
    notes = []  # (the capture's caveats are the photos table's notes)
    if side < config.protocol.longest_side:
        notes.append(f"rendered at {side} px (the photos' size), not {config.protocol.longest_side} px: "
                     "a photo is never upsampled")
    return RealViews(protocol.name, train, test, photos, c.source, notes, side), None
