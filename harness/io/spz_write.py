"""Niantic ``.spz`` writer (versions 2, 3 and 4; 4 by default, as Niantic's and splat-transform's).

The encoder of nianticlabs/spz ``src/cc/load-spz.cc`` (``packGaussians``, ``saveSpz``,
``serializePackedGaussians``, ``packQuaternionSmallestThree``, ``packQuaternionFirstThree``,
``quantizeSH``; commit 21715c3), read and restated in numpy with its float32 arithmetic and
``std::round`` (half away from zero). Layout: see :mod:`harness.io.spz` (the reader).

Per splat (``round`` half away from zero, ``u8(v) = clamp(round(v), 0, 255)``, all float32):

* position: ``round(x · 2^f)`` as 24-bit two's complement; ``f`` = 12 fractional bits (Niantic's
  constant) unless a coordinate reaches 2048, then the largest ``f`` that holds every coordinate
  (the header carries ``f``; readers honour it). Beyond 2^23 units nothing fits: refused.
* log-scale ``u8((s + 10)·16)``; alpha ``u8(sigmoid(o)·255)``; colour ``u8(f_dc·0.15·255 + 127.5)``.
* rotation, v3/v4: ``q`` normalised (x, y, z, w order), the index of the largest |component| in
  the top 2 bits, then for each other component in order a sign bit (relative to the largest,
  which is made positive) and ``m = trunc(511·|q_i|/√½ + 0.5)`` in 9 bits. ``m`` is clamped to 511:
  float32 rounding can give 512 for two components of equal size, which the reference would let
  spill into the sign bit. v2: ``u8(q·(±127.5) + 127.5)`` for x, y, z with w made positive.
* SH coefficient ``c`` (coefficient-major, RGB innermost): ``q = round(c·128) + 128`` snapped to a
  bucket centre, ``(q + b/2)/b·b`` (C integer division), clamped to 0..255; ``b`` = 8 for degree 1
  (5 bits) and 16 beyond (4 bits), Niantic's defaults.

Axes are the PLY axes, unchanged (``PackOptions.from`` unspecified, as Niantic's ``ply_to_spz``
and splat-transform ≥ 3 write them; no coordinate-system record). Flags 0 (not antialiased).
Containers: v4 = 32-byte plaintext header, table of (compressed, uncompressed) u64 sizes, one zstd
frame per non-empty stream (level 12, as Niantic); v2/v3 = one gzip stream of the 16-byte header
and the streams (mtime 0, so equal scenes give equal files). Lossy (bounds in ``tests/test_convert.py``);
extra properties and header comments are not stored. Decoding the output with
:func:`harness.io.spz.read_spz` and encoding it again gives the same bytes for every stream but
rotations (re-normalising a decoded quaternion can move a 9-bit magnitude by one step).
"""

from __future__ import annotations

import gzip
import struct

import numpy as np

from harness.core.errors import InputError
from harness.core.scene import GaussianScene
from harness.io.codecs import round_half_away
from harness.io.files import atomic_write_chunks

VERSIONS = (2, 3, 4)
DEFAULT_VERSION = 4
FRACTIONAL_BITS = 12
_F = np.float32
_SQRT1_2 = _F(0.70710678118654752440)
_COLOUR_SCALE = _F(0.15)
_SH1_BUCKET, _SH_REST_BUCKET = 1 << (8 - 5), 1 << (8 - 4)
_V4 = struct.Struct("<4sIIBBBBI12x")
_LEGACY = struct.Struct("<4sIIBBBB")
_LIMIT = (1 << 23) - 1


def _u8(v: np.ndarray) -> np.ndarray:
    """``toUint8``: clamp(round(v), 0, 255)."""
    return np.clip(round_half_away(v), 0, 255).astype(np.uint8)


def fractional_bits(means: np.ndarray, source="scene") -> int:
    """12, or fewer when a coordinate would not fit 24 bits (module docstring)."""
    m = np.abs(np.asarray(means, _F)).max(initial=0.0)
    for bits in range(FRACTIONAL_BITS, -1, -1):
        if round_half_away(_F(m) * _F(1 << bits)) <= _LIMIT:
            return bits
    raise InputError(source, f"a splat centre is {float(m):.4g} units from the origin; spz's 24-bit fixed point "
                             f"holds at most {_LIMIT:,} units")


def position_error(means: np.ndarray) -> np.ndarray:
    """How far writing moves each centre (max over axes): ``|round(x·2^f)/2^f − x|``."""
    bits = fractional_bits(means)
    m = np.asarray(means, _F)
    fixed = round_half_away(m * _F(1 << bits)).astype(np.float64)
    return np.abs(fixed / (1 << bits) - m).max(1, initial=0.0)


def _positions(means: np.ndarray, bits: int) -> np.ndarray:
    fixed = round_half_away(np.asarray(means, _F) * _F(1 << bits)).astype(np.int32)
    return np.stack([fixed & 0xFF, (fixed >> 8) & 0xFF, (fixed >> 16) & 0xFF], axis=-1).astype(np.uint8).reshape(-1)


def _normalised_xyzw(quats_wxyz: np.ndarray) -> np.ndarray:
    q = np.asarray(quats_wxyz, _F)[:, [1, 2, 3, 0]]
    return q / np.sqrt((q * q).sum(axis=1, dtype=_F))[:, None]


def _rotations_smallest_three(quats_wxyz: np.ndarray) -> np.ndarray:
    q = _normalised_xyzw(quats_wxyz)
    n = len(q)
    largest = np.abs(q).argmax(axis=1)  # first of equal maxima, as the reference's strict '>'
    negate = q[np.arange(n), largest] < 0
    comp = largest.astype(np.uint32)
    for i in range(4):
        keep = largest != i
        neg = ((q[:, i] < 0) ^ negate).astype(np.uint32)
        mag = np.minimum(np.trunc(_F(511.0) * (np.abs(q[:, i]) / _SQRT1_2) + _F(0.5)), 511).astype(np.uint32)
        comp = np.where(keep, (comp << np.uint32(10)) | (neg << np.uint32(9)) | mag, comp)
    return comp.astype("<u4").view(np.uint8).reshape(-1)


def _rotations_first_three(quats_wxyz: np.ndarray) -> np.ndarray:
    q = _normalised_xyzw(quats_wxyz)
    q = q * np.where(q[:, 3] < 0, _F(-127.5), _F(127.5))[:, None] + _F(127.5)
    return _u8(q[:, :3]).reshape(-1)


def _sh(sh_rest: np.ndarray) -> np.ndarray:
    """(N, K, 3) coefficients -> (N·K·3,) bytes, coefficient-major with RGB innermost."""
    n, k, _ = sh_rest.shape
    q = (round_half_away(np.asarray(sh_rest, _F) * _F(128.0)) + _F(128.0)).astype(np.int32)
    bucket = np.where(np.arange(k) < 3, _SH1_BUCKET, _SH_REST_BUCKET)[None, :, None]
    t = q + bucket // 2
    snapped = np.where(t >= 0, t // bucket, -((-t) // bucket)) * bucket  # C division truncates
    return np.clip(snapped, 0, 255).astype(np.uint8).reshape(-1)


def encode_streams(scene: GaussianScene, version: int = DEFAULT_VERSION, source="scene") -> tuple[int, list[bytes]]:
    """(fractional bits, [positions, alphas, colours, scales, rotations, sh]) as stored."""
    if not isinstance(version, (int, np.integer)) or isinstance(version, bool):
        raise InputError("spz_version", f"must be an integer ({', '.join(map(str, VERSIONS))}), "
                                        f"got {version!r} ({type(version).__name__})")
    if version not in VERSIONS:
        raise InputError(source, f"spz version {version} cannot be written (choose {', '.join(map(str, VERSIONS))})")
    bits = fractional_bits(scene.means, source)
    alpha = _F(1.0) / (_F(1.0) + np.exp(-np.asarray(scene.opacity_logit, _F)))
    colour = np.asarray(scene.sh_dc, _F) * (_COLOUR_SCALE * _F(255.0)) + _F(0.5) * _F(255.0)
    rot = _rotations_smallest_three if version >= 3 else _rotations_first_three
    streams = [_positions(scene.means, bits), _u8(alpha * _F(255.0)), _u8(colour).reshape(-1),
               _u8((np.asarray(scene.scales_log, _F) + _F(10.0)) * _F(16.0)).reshape(-1), rot(scene.quats),
               _sh(scene.sh_rest)]
    return bits, [s.tobytes() for s in streams]


def encode_spz(scene: GaussianScene, version: int = DEFAULT_VERSION, source="scene") -> list[bytes]:
    """The file's bytes, in pieces (module docstring)."""
    if len(scene) == 0:
        raise InputError(source, "an spz file cannot hold 0 splats (the reference loader rejects it)")
    bits, streams = encode_streams(scene, version, source)
    n, degree = len(scene), scene.sh_degree
    if version < 4:
        header = _LEGACY.pack(b"NGSP", version, n, degree, bits, 0, 0)
        return [gzip.compress(header + b"".join(streams), compresslevel=6, mtime=0)]
    import zstandard

    compressor = zstandard.ZstdCompressor(level=12)
    frames = [(compressor.compress(s), len(s)) for s in streams if s]
    toc = b"".join(struct.pack("<QQ", len(c), u) for c, u in frames)
    header = _V4.pack(b"NGSP", 4, n, degree, bits, 0, len(frames), _V4.size)
    return [header, toc, *(c for c, _ in frames)]


def write_spz(scene: GaussianScene, path, version: int = DEFAULT_VERSION) -> None:
    """Write ``scene`` as ``.spz`` (atomically; lossy, see module docstring)."""
    atomic_write_chunks(path, encode_spz(scene, version, path))
