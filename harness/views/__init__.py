"""Where to look from: the view protocols a run measures (:mod:`.protocols`, the built-ins in
:mod:`.heldout`), synthetic rigs for scenes without cameras, the placement statistics they use,
contact sheets. Imports harness.core and harness.io.

A third-party view protocol: ``from harness.views import register_protocol, ViewRequest`` (see
:mod:`.protocols`)."""

from harness.views.protocols import HeldOut, NoViews, ViewRequest, ViewSizes, register_protocol

__all__ = ["HeldOut", "NoViews", "ViewRequest", "ViewSizes", "register_protocol"]
