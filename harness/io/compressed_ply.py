"""PlayCanvas / SuperSplat ``compressed.ply``: decoder (from parsed PLY elements) and writer.

Layout, as read and written by PlayCanvas splat-transform (``src/lib/readers/decompress-ply.ts``,
``src/lib/writers/write-compressed-ply.ts``, ``compressed-chunk.ts``, commit 8d6b801, v3.2.0)::

    element chunk C       C = ceil(N / 256); float properties
        min_x min_y min_z max_x max_y max_z
        min_scale_x min_scale_y min_scale_z max_scale_x max_scale_y max_scale_z
        [min_r min_g min_b max_r max_g max_b]         (12 properties in old SuperSplat files)
    element vertex N      uint packed_position packed_rotation packed_scale packed_color
    [element sh N]        uchar f_rest_0 .. f_rest_{3K-1}, K = 3, 8, 15 (or none: gsplat's SH0)

Decoding splat ``i`` with chunk ``c = i // 256``, ``lerp(a, b, t) = a·(1 − t) + b·t`` and
``unorm`` from :mod:`harness.io.codecs`:

* position, log-scale: ``lerp(min[c], max[c], t)`` with ``t`` the 11/10/11-bit fields at bits
  21, 11, 0 (x, y, z). Axes are the PLY axes.
* rotation: bits 30-31 index the largest of (w, x, y, z) (INRIA ``rot_0..3`` order); the other
  three, in order, are ``(unorm(10 bits at 20, 10, 0) − 0.5)·√2``; smallest-three reconstruction.
* colour: bytes R, G, B, A from the most significant down. With a chunk colour range
  ``rgb = lerp(min_rgb[c], max_rgb[c], byte/255)``, else ``byte/255``; ``f_dc = (rgb − 0.5)/SH_C0``.
  A is linear alpha (``opacity = logit``, bytes 0/255 clamped as in :mod:`harness.io.codecs`).
* SH: byte q -> ``n = 0 (q = 0), 1 (q = 255), (q + 0.5)/256`` otherwise; ``f_rest = (n − 0.5)·8``,
  in the INRIA channel-major order ``f_rest_{c·K + k}``.

Writing (:func:`write_compressed_ply`) is splat-transform's encoder: splats are put in Morton order
of their positions (10 bits per axis over the bounding box; **the output row order differs from
the scene's**), chunk ranges are the min/max of each run of 256 (scale ranges clamped to [−20, 20]),
``pack = clamp(floor(t·(2^bits − 1) + 0.5))``, the quaternion is normalised and negated so its
largest component is positive, SH bytes are ``clamp(trunc((f/8 + 0.5)·256), 0, 255)``. Lossy:
error bounds per field are in ``tests/test_formats_compressed_ply.py``. Extra properties are dropped.
"""

from __future__ import annotations

import numpy as np

from harness.core.errors import InputError
from harness.core.scene import (
    SH_C0,
    SH_REST_COUNT,
    GaussianScene,
    normalized_quats,
    sigmoid,
)
from harness.io.codecs import LOGIT_OF_ALPHA_BYTE, smallest_three, unorm
from harness.io.files import atomic_write_chunks

CHUNK = 256
_AXES = ("x", "y", "z")
_RANGE_PROPS = [f"min_{a}" for a in _AXES] + [f"max_{a}" for a in _AXES] \
    + [f"min_scale_{a}" for a in _AXES] + [f"max_scale_{a}" for a in _AXES]
_COLOUR_PROPS = [f"min_{c}" for c in "rgb"] + [f"max_{c}" for c in "rgb"]
_PACKED = ("packed_position", "packed_rotation", "packed_scale", "packed_color")
_SQRT2 = np.sqrt(2.0)
_SCALE_LIMIT = 20.0
_Q = np.arange(256, dtype=np.float64)
_SH_OF_BYTE = ((np.where(_Q == 0, 0.0, np.where(_Q == 255, 1.0, (_Q + 0.5) / 256.0)) - 0.5) * 8.0).astype(np.float32)


def is_compressed_ply(header) -> bool:
    """True for a PLY header with a ``chunk`` element and ``packed_*`` vertex properties."""
    vertex = header.element("vertex")
    return header.element("chunk") is not None and vertex is not None \
        and any(name == "packed_position" for name, _ in vertex.properties)


def describe(header) -> str:
    """What ``harness info`` calls the file, from its header alone."""
    sh = header.element("sh")
    k = len(sh.properties) // 3 if sh is not None else 0
    degree = {v: d for d, v in SH_REST_COUNT.items()}.get(k, "?")
    return f"compressed-ply (PlayCanvas, {header.element('chunk').count} chunks, SH degree {degree})"


def _check_layout(elements: dict[str, np.ndarray], source) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """(chunk rows, vertex rows, sh bytes (N, 3K) or None) after checking the schema and counts."""
    extra = sorted(set(elements) - {"chunk", "vertex", "sh"})
    if extra:
        raise InputError(source, f"compressed.ply has an unexpected element {extra[0]!r} "
                                 "(expected chunk, vertex and optionally sh)")
    chunk, vertex = elements["chunk"], elements["vertex"]
    names = chunk.dtype.names or ()
    missing = [p for p in _RANGE_PROPS if p not in names]
    if missing or any(chunk.dtype[p].kind != "f" for p in names):
        raise InputError(source, "compressed.ply chunk element must hold float properties "
                                 f"{', '.join(_RANGE_PROPS[:3])}, ... (missing or not float: "
                                 f"{(missing or [p for p in names if chunk.dtype[p].kind != 'f'])[0]})")
    bad = [p for p in _PACKED if p not in (vertex.dtype.names or ()) or vertex.dtype[p].str[1:] != "u4"]
    if bad:
        raise InputError(source, f"compressed.ply vertex property {bad[0]} is missing or not a uint")
    n, c = len(vertex), len(chunk)
    if c != -(-n // CHUNK):
        raise InputError(source, f"compressed.ply has {c} chunks for {n} splats; "
                                 f"expected ceil({n}/256) = {-(-n // CHUNK)}")
    sh = elements.get("sh")
    if sh is None or not sh.dtype.names:
        return chunk, vertex, None
    m = len(sh.dtype.names)
    if m not in (9, 24, 45) or len(sh) != n:
        raise InputError(source, f"compressed.ply sh element has {m} properties and {len(sh)} rows; "
                                 f"expected 9, 24 or 45 and {n}")
    expected = [f"f_rest_{i}" for i in range(m)]
    if list(sh.dtype.names) != expected or any(sh.dtype[p].str[1:] != "u1" for p in expected):
        raise InputError(source, "compressed.ply sh properties must be uchar f_rest_0 .. f_rest_"
                                 f"{m - 1} in order")
    return chunk, vertex, sh.view(np.uint8).reshape(n, m)


def decode_compressed_ply(elements: dict[str, np.ndarray], source) -> GaussianScene:
    """The scene held by the parsed elements of a compressed.ply (module docstring has the math)."""
    chunk, vertex, sh = _check_layout(elements, source)
    with np.errstate(invalid="ignore", over="ignore"):  # non-finite ranges: reported by scene validation
        return _decode(chunk, vertex, sh)


def _decode(chunk: np.ndarray, vertex: np.ndarray, sh: np.ndarray | None) -> GaussianScene:
    n = len(vertex)
    ci = np.arange(n) // CHUNK
    bound = lambda *names: np.stack([chunk[p].astype(np.float64) for p in names], 1)[ci]  # noqa: E731

    def lerp(lo, hi, t):
        return lo * (1.0 - t) + hi * t

    def fields_111011(packed):
        return np.stack([unorm(packed, 21, 11), unorm(packed, 11, 10), unorm(packed, 0, 11)], 1)

    means = lerp(bound("min_x", "min_y", "min_z"), bound("max_x", "max_y", "max_z"),
                 fields_111011(vertex["packed_position"]))
    scales_log = lerp(bound("min_scale_x", "min_scale_y", "min_scale_z"),
                      bound("max_scale_x", "max_scale_y", "max_scale_z"), fields_111011(vertex["packed_scale"]))
    rot = vertex["packed_rotation"]
    others = (np.stack([unorm(rot, 20, 10), unorm(rot, 10, 10), unorm(rot, 0, 10)], 1) - 0.5) * _SQRT2
    quats = smallest_three(rot >> np.uint32(30), others)
    col = vertex["packed_color"]
    rgb = np.stack([unorm(col, 24, 8), unorm(col, 16, 8), unorm(col, 8, 8)], 1)
    if all(p in chunk.dtype.names for p in _COLOUR_PROPS):
        rgb = lerp(bound("min_r", "min_g", "min_b"), bound("max_r", "max_g", "max_b"), rgb)
    sh_rest = None
    if sh is not None:
        k = sh.shape[1] // 3
        sh_rest = _SH_OF_BYTE[sh].reshape(n, 3, k).transpose(0, 2, 1)  # f_rest_{c*K+k} -> [k, c]
    return GaussianScene.from_arrays(means, scales_log, quats, LOGIT_OF_ALPHA_BYTE[col & np.uint32(0xFF)],
                                     (rgb - 0.5) / SH_C0, sh_rest)


# ---------------------------------------------------------------------- writing
def morton_order(means: np.ndarray) -> np.ndarray:
    """Row order sorting positions along a Z-order curve (10 bits per axis over the bounding box)."""
    if len(means) == 0:
        return np.zeros(0, np.int64)
    lo, hi = means.min(0).astype(np.float64), means.max(0).astype(np.float64)
    cell = np.clip((means - lo) / np.where(hi > lo, hi - lo, 1.0) * 1023.0, 0, 1023).astype(np.uint64)
    code = np.zeros(len(means), np.uint64)
    for bit in range(10):
        for axis in range(3):
            code |= ((cell[:, axis] >> np.uint64(bit)) & np.uint64(1)) << np.uint64(3 * bit + 2 - axis)
    return np.argsort(code, kind="stable")


def _chunk_ranges(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-chunk (min, max), (C, D) float32; the last chunk is padded with its last row."""
    n, d = values.shape
    c = -(-n // CHUNK)
    padded = np.concatenate([values, np.repeat(values[-1:], c * CHUNK - n, axis=0)])
    blocks = padded.reshape(c, CHUNK, d)
    return blocks.min(1).astype(np.float32), blocks.max(1).astype(np.float32)


def _pack_unorm(t: np.ndarray, bits: int) -> np.ndarray:
    top = (1 << bits) - 1
    return np.clip(np.floor(t * top + 0.5), 0, top).astype(np.uint32)


def _normalise(values: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """splat-transform's ``normalize``: 0 below/at min, 1 at/above max, 0 for a range < 1e-5."""
    ci = np.arange(len(values)) // CHUNK
    lo, hi = lo.astype(np.float64)[ci], hi.astype(np.float64)[ci]
    span = hi - lo
    t = np.where(span < 1e-5, 0.0, (values - lo) / np.where(span < 1e-5, 1.0, span))
    return np.where(values <= lo, 0.0, np.where(values >= hi, 1.0, t))


def _pack_111011(t: np.ndarray) -> np.ndarray:
    return (_pack_unorm(t[:, 0], 11) << np.uint32(21)) | (_pack_unorm(t[:, 1], 10) << np.uint32(11)) \
        | _pack_unorm(t[:, 2], 11)


def _pack_rotation(quats: np.ndarray) -> np.ndarray:
    q = normalized_quats(quats.astype(np.float64))
    largest = np.abs(q).argmax(1)
    q = q * np.where(q[np.arange(len(q)), largest] < 0, -1.0, 1.0)[:, None]
    slots = np.array([[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]])[largest]
    others = _pack_unorm(q[np.arange(len(q))[:, None], slots] / _SQRT2 + 0.5, 10)
    return (largest.astype(np.uint32) << np.uint32(30)) | (others[:, 0] << np.uint32(20)) \
        | (others[:, 1] << np.uint32(10)) | others[:, 2]


def position_error(means: np.ndarray) -> np.ndarray:
    """How far writing moves each centre (max over axes, scene order): its chunk's range at 11/10/11 bits."""
    n = len(means)
    if n == 0:
        return np.zeros(0)
    order = morton_order(means)
    m = np.asarray(means, np.float32)[order]
    lo, hi = _chunk_ranges(m)
    t = _normalise(m.astype(np.float64), lo, hi)
    ci = np.arange(n) // CHUNK
    moved = np.zeros(n)
    for axis, bits in enumerate((11, 10, 11)):
        a, b = lo[ci, axis].astype(np.float64), hi[ci, axis].astype(np.float64)
        u = _pack_unorm(t[:, axis], bits) / ((1 << bits) - 1)
        moved = np.maximum(moved, np.abs(a * (1 - u) + b * u - m[:, axis]))
    out = np.empty(n)
    out[order] = moved
    return out


def encode_compressed_ply(scene: GaussianScene, comments=None, preamble=None) -> tuple[list, np.ndarray]:
    """(header bytes and data arrays, row order): file row ``j`` holds ``scene`` row ``order[j]``.
    Header comments default to the scene's own (``scene.meta``), each before or after ``format``."""
    comments = scene.meta.comments if comments is None else comments
    preamble = scene.meta.preamble if preamble is None else preamble
    order = morton_order(scene.means)
    s = scene.subset(order)
    n, k = len(s), s.sh_rest.shape[1]
    chunks = -(-n // CHUNK)
    rgb = s.sh_dc.astype(np.float64) * SH_C0 + 0.5
    table = np.zeros((chunks, 18), np.float32)
    vertex = np.zeros((n, 4), np.uint32)
    if n:
        pos_lo, pos_hi = _chunk_ranges(s.means)
        scale_lo, scale_hi = (np.clip(r, -_SCALE_LIMIT, _SCALE_LIMIT) for r in _chunk_ranges(s.scales_log))
        rgb_lo, rgb_hi = _chunk_ranges(rgb)
        table[:] = np.concatenate([pos_lo, pos_hi, scale_lo, scale_hi, rgb_lo, rgb_hi], 1)
        alpha = _pack_unorm(sigmoid(s.opacity_logit.astype(np.float64)), 8)
        colour = _pack_unorm(_normalise(rgb, rgb_lo, rgb_hi), 8)
        vertex[:, 0] = _pack_111011(_normalise(s.means.astype(np.float64), pos_lo, pos_hi))
        vertex[:, 1] = _pack_rotation(s.quats)
        vertex[:, 2] = _pack_111011(_normalise(s.scales_log.astype(np.float64), scale_lo, scale_hi))
        vertex[:, 3] = (colour[:, 0] << np.uint32(24)) | (colour[:, 1] << np.uint32(16)) \
            | (colour[:, 2] << np.uint32(8)) | alpha
    rest = s.sh_rest.astype(np.float64).transpose(0, 2, 1).reshape(n, 3 * k)  # [k, c] -> f_rest_{c*K+k}
    sh = np.clip(np.trunc((rest / 8.0 + 0.5) * 256.0), 0, 255).astype(np.uint8)
    lines = ["ply", *(f"comment {c}" for c in preamble), "format binary_little_endian 1.0",
             *(f"comment {c}" for c in comments),
             f"element chunk {chunks}", *(f"property float {p}" for p in _RANGE_PROPS + _COLOUR_PROPS),
             f"element vertex {n}", *(f"property uint {p}" for p in _PACKED)]
    if k:
        lines += [f"element sh {n}", *(f"property uchar f_rest_{i}" for i in range(3 * k))]
    header = ("\n".join(lines + ["end_header"]) + "\n").encode("ascii")
    return [header, table.astype("<f4"), vertex.astype("<u4"), sh], order


def write_compressed_ply(scene: GaussianScene, path, *, comments=None, preamble=None) -> np.ndarray:
    """Write ``scene`` as a compressed.ply (atomically; lossy, reordered); returns the row order."""
    data, order = encode_compressed_ply(scene, comments, preamble)
    atomic_write_chunks(path, data)
    return order
