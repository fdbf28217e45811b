"""Checking a torch device named by a user (``--device``, ``protocol.device``) before any work.

``cpu`` always works; ``cuda``/``cuda:N`` only when a CUDA device is present (and N exists);
``mps`` only when available. Anything else (``meta``, ``xla``, a typo) is an
:class:`~harness.core.errors.InputError`: a device that cannot hold real tensors must fail as one
line before a scene is read, not as a traceback in the middle of a render.

``"cpu"`` itself is answered without importing torch (1–2 CPU-s and ~0.9 GiB mapped): commands
that pass the default ``--device cpu`` but never compute with torch (``prune`` with a
camera-agnostic pruner) must not pay for it. Every other spelling is checked by torch.
"""

from __future__ import annotations

from harness.core.errors import InputError

SUPPORTED = ("cpu", "cuda", "mps")


def check_device(text: str | None, source: str = "--device") -> str | None:
    """``text`` unchanged when usable (None passes through: the caller's default)."""
    if text is None:
        return None
    if text == "cpu":  # always usable; torch is not imported to say so (module docstring)
        return text
    import torch

    try:
        dev = torch.device(str(text))
    except (RuntimeError, ValueError, TypeError) as err:
        raise InputError(source, f"not a torch device: {str(err).splitlines()[0] if str(err) else text!r}") from None
    if dev.type not in SUPPORTED:
        raise InputError(source, f"device type {dev.type!r} cannot run the harness; use one of {', '.join(SUPPORTED)}")
    if dev.type == "cuda":
        if not torch.cuda.is_available():
            raise InputError(source, f"{text} requested but no CUDA device is available")
        if dev.index is not None and dev.index >= torch.cuda.device_count():
            raise InputError(source, f"{text} requested but only {torch.cuda.device_count()} CUDA device(s) exist")
    if dev.type == "mps" and not (getattr(torch.backends, "mps", None) and torch.backends.mps.is_available()):
        raise InputError(source, f"{text} requested but MPS is not available")
    return str(text)


def default_device() -> str:
    """The device to compute on when none is named: ``"cuda"`` on a machine with an NVIDIA GPU that
    torch can use, else ``"cpu"`` — decided without importing torch where there is no NVIDIA device
    node (``/dev/nvidiactl``), so CPU-only commands never load it."""
    from pathlib import Path

    if not Path("/dev/nvidiactl").exists():
        return "cpu"
    import torch

    return "cuda" if torch.cuda.is_available() else "cpu"
