"""antimatter15 ``.splat``: headerless 32-byte little-endian records.

Record: position 3×f32 | linear scale 3×f32 | RGBA 4×u8 | rotation 4×u8 (w, x, y, z).

Decoding to stored (pre-activation) parameters, inverting the encoder
(RGB = 0.5 + SH_C0·f_dc, A = sigmoid(opacity), byte = q·128 + 128 with q normalised):

* ``scales_log = log(scale)``; a non-positive scale gives -inf/NaN and is reported by validation.
* ``sh_dc = (RGB/255 − 0.5) / SH_C0``. Colours the encoder clamped at 0 or 255 cannot be recovered.
* ``opacity_logit = logit(clip(A/255, ¼/255, 1 − ¼/255))``: A = 0 or 255 would give ∓inf, so they
  are clamped a quarter quantisation step inside (close enough to re-encode to the same byte); the
  opacity ¼/255 keeps every pixel of the splat below the renderer's 1/255 alpha cut-off, as A = 0
  implies.
* ``quats = (byte − 128) / 128`` (not renormalised; consumers normalise on use). All four bytes
  equal to 128 decode to a zero-norm quaternion, which validation rejects.
* SH degree 0, no extra properties.

Encoding (:func:`write_splat`) is the antimatter15 ``convert.py`` mapping with rounding instead of
truncation. Writing ``.splat`` is a lossy export. "Round trip" for a ``.splat`` input therefore means
read ``.splat`` -> write ``.ply`` -> read ``.ply`` gives identical arrays. Re-encoding a decoded file
reproduces its position, colour and alpha bytes exactly and its scales to float rounding; rotation
bytes may move by one step because the encoder normalises the (quantised, not unit) quaternion.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from harness.core.errors import InputError
from harness.core.scene import SH_C0, GaussianScene, normalized_quats, sigmoid
from harness.io.codecs import LOGIT_OF_ALPHA_BYTE
from harness.io.files import atomic_write_chunks

SPLAT_RECORD = np.dtype([("pos", "<f4", (3,)), ("scale", "<f4", (3,)), ("rgba", "u1", (4,)), ("rot", "u1", (4,))])
assert SPLAT_RECORD.itemsize == 32
_BYTES = np.arange(256, dtype=np.float64)
# byte -> value tables, computed in float64 and rounded once to float32
_DC_OF_BYTE = ((_BYTES / 255.0 - 0.5) / SH_C0).astype(np.float32)
_QUAT_OF_BYTE = ((_BYTES - 128.0) / 128.0).astype(np.float32)


def read_splat(path: str | Path) -> GaussianScene:
    """Read an antimatter15 ``.splat`` file (see module docstring for the decoding)."""
    import os

    from harness.io.safe import open_regular

    path = Path(path)
    with open_regular(path, "scene", ".splat file") as f:
        size = os.fstat(f.fileno()).st_size
        _check_size(path, size)
        rec = np.fromfile(f, dtype=SPLAT_RECORD, count=size // SPLAT_RECORD.itemsize)
    if len(rec) * SPLAT_RECORD.itemsize != size:
        raise InputError(path, "truncated while reading")
    rgba = np.ascontiguousarray(rec["rgba"])
    with np.errstate(divide="ignore", invalid="ignore"):
        scales_log = np.log(rec["scale"])
    return GaussianScene.from_arrays(
        means=rec["pos"],
        scales_log=scales_log,
        quats=_QUAT_OF_BYTE[rec["rot"]],
        opacity_logit=LOGIT_OF_ALPHA_BYTE[rgba[:, 3]],
        sh_dc=_DC_OF_BYTE[rgba[:, :3]],
    )


def _check_size(path: Path, size: int) -> None:
    if size == 0:
        raise InputError(path, "empty .splat file (no 32-byte records)")
    if size % SPLAT_RECORD.itemsize:
        raise InputError(path, f"truncated: {size} bytes is not a whole number of 32-byte .splat records "
                               f"({size // 32} complete, {size % 32} bytes left over)")


def encode_splat(scene: GaussianScene) -> np.ndarray:
    """The scene as ``.splat`` records (SH beyond degree 0 and extras are dropped)."""
    rec = np.empty(len(scene), dtype=SPLAT_RECORD)
    rec["pos"] = scene.means
    rec["scale"] = np.exp(scene.scales_log)
    rgb = 0.5 + SH_C0 * scene.sh_dc.astype(np.float64)
    rgba = np.concatenate([rgb, sigmoid(scene.opacity_logit.astype(np.float64))[:, None]], axis=1)
    rec["rgba"] = np.clip(np.rint(rgba * 255.0), 0, 255).astype(np.uint8)
    q = normalized_quats(scene.quats.astype(np.float64))
    rec["rot"] = np.clip(np.rint(q * 128.0 + 128.0), 0, 255).astype(np.uint8)
    return rec


def write_splat(scene: GaussianScene, path: str | Path) -> None:
    """Write ``scene`` as an antimatter15 ``.splat`` file (atomically; lossy, see module docstring)."""
    atomic_write_chunks(path, [encode_splat(scene)])
