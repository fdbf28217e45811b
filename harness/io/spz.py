"""Niantic ``.spz`` (versions 1-4): header probe and reader.

Layout (nianticlabs/spz ``src/cc/load-spz.cc``, ``splat-utils.h``, ``splat-types.h``, ``README.md``,
``extensions/``, commit 21715c3):

* v1-v3: one gzip stream holding a 16-byte header ``u32 magic "NGSP" | u32 version |
  u32 numPoints | u8 shDegree | u8 fractionalBits | u8 flags | u8 reserved`` followed by the
  attribute streams back to back, then extension records when ``flags & 2``.
* v4: a plaintext 32-byte header ``magic | version | numPoints | shDegree | fractionalBits | flags |
  u8 numStreams | u32 tocByteOffset | 12 reserved``; extension records in ``[32, tocByteOffset)``;
  a table of ``numStreams × (u64 compressed, u64 uncompressed)`` sizes; then one zstd frame per
  non-empty stream.
* Streams, in order, for N points and ``dim = 0, 3, 8, 15, 24`` SH coefficients (degree 0-4):
  positions 9N (v1: 6N float16) | alphas N | colours 3N | scales 3N | rotations 3N (v1-2) or
  4N (v3+) | SH 3·dim·N, coefficient-major with RGB innermost.

Decoding (``unpackGaussians``):

* position: 24-bit two's-complement little-endian fixed point, ``x = fixed / 2^fractionalBits``.
* log-scale ``= byte/16 − 10``; alpha ``= byte/255`` (linear; logit as in :mod:`harness.io.codecs`);
  ``f_dc = (byte/255 − 0.5) / 0.15``; SH ``= (byte − 128)/128``.
* rotation (x, y, z, w): v3+ "smallest three" in a little-endian u32: bits 30-31 index the largest,
  then three 10-bit fields (ascending component order, high bits first), each a sign bit (bit 9)
  and a magnitude ``m``: ``±m/511·√½``. v1-2: ``xyz = byte/127.5 − 1``, ``w = sqrt(max(0, 1 − |xyz|²))``.

Axes. The format has no header field for the axis convention. Niantic's README says spz stores
RUB "by default", but its packer converts only when the caller names a source system (``PackOptions.from``
defaults to UNSPECIFIED: no conversion), and the writers in use store the PLY axes unchanged:
Niantic's CLI ``ply_to_spz``, splat-transform ≥ 3.0 (``spz-module.ts`` @8d6b801), gsply 0.4.6,
gaussforge 0.6.0, spz-js 1.2.5 (verified on their output: ``tests/fixtures/formats``); only
splat-transform 2.x wrote RUB. So files are read with the PLY axes unchanged unless a v4 (or
legacy) ``SPZ_ADOBE_coordinate_system`` record (type 0xADBE0003, payload u32 system, UNSPECIFIED
meaning RUB per ``coordinate-system-adobe.cc``) states the stored system; ``axes=`` overrides.
Conversion from a system of the standard family (LDB..RUF) to PLY's RDF flips axes by
``s = (sx, sy, sz)``: positions ``·s``, quaternion (x, y, z) ``·(sy·sz, sx·sz, sx·sy)``, SH
coefficient k ``·flipSh[k]`` (``coordinateConverter``); axis-permuting systems are not supported.

Limits (checked before anything large is allocated): the decompressed size the header implies may
not exceed 1024 × the file size (Niantic's ``kMaxCompressionRatio``, applied to all streams rather
than positions only); v4 stream sizes must equal what the header implies and the frames must fill
the file; decompression stops at the size the header implies, so a bomb cannot allocate more.
Zero points and SH degree 4 are rejected (the reference rejects the first; the scene model holds
SH degrees 0-3).
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from harness.core.errors import InputError
from harness.core.scene import GaussianScene
from harness.io.codecs import LOGIT_OF_ALPHA_BYTE, smallest_three, xyzw_to_wxyz

MAGIC = b"NGSP"
GZIP_MAGIC = b"\x1f\x8b"
PROBE_BYTES = 1 << 16  # enough gzip input to inflate the 16-byte legacy header
_LEGACY = struct.Struct("<4sIIBBBB")
_V4 = struct.Struct("<4sIIBBBBI12x")
_SH_DIM = {0: 0, 1: 3, 2: 8, 3: 15, 4: 24}
_MAX_RATIO = 1024  # load-spz.cc kMaxCompressionRatio
_COORDINATE_SYSTEM_RECORD = 0xADBE0003
_MAX_TRAILING_EXTENSION_BYTES = 1 << 20
#: CoordinateSystem values of the standard family (splat-types.h); PLY is RDF
SYSTEMS = {"LDB": 1, "RDB": 2, "LUB": 3, "RUB": 4, "LDF": 5, "RDF": 6, "LUF": 7, "RUF": 8}
_SYSTEM_NAMES = {v: k for k, v in SYSTEMS.items()}
_B = np.arange(256, dtype=np.float64)
_SCALE_OF_BYTE = (_B / 16.0 - 10.0).astype(np.float32)
_DC_OF_BYTE = ((_B / 255.0 - 0.5) / 0.15).astype(np.float32)
_SH_OF_BYTE = ((_B - 128.0) / 128.0).astype(np.float32)


@dataclass(frozen=True)
class SpzHeader:
    version: int
    points: int
    sh_degree: int
    fractional_bits: int
    flags: int
    container: str                 # "gzip" (v1-3) or "zstd" (v4, plaintext NGSP header)
    streams: int | None = None     # v4 only
    toc_offset: int | None = None  # v4 only

    def stream_sizes(self) -> list[int]:
        n, dim = self.points, _SH_DIM[self.sh_degree]
        return [n * (6 if self.version == 1 else 9), n, 3 * n, 3 * n, n * (4 if self.version >= 3 else 3), 3 * dim * n]


def probe(head: bytes) -> SpzHeader | None:
    """The header of an spz file from its first bytes, or None when they are not spz."""
    if head[:4] == MAGIC and len(head) >= _V4.size:
        _, version, n, sh, fb, flags, streams, toc = _V4.unpack_from(head)
        return SpzHeader(version, n, sh, fb, flags, "zstd", streams, toc)
    if head[:2] == GZIP_MAGIC:
        try:
            raw = zlib.decompressobj(16 + zlib.MAX_WBITS).decompress(head, _LEGACY.size)
        except zlib.error:
            return None
        if len(raw) == _LEGACY.size and raw[:4] == MAGIC:
            _, version, n, sh, fb, flags, _ = _LEGACY.unpack(raw)
            return SpzHeader(version, n, sh, fb, flags, "gzip")
    return None


def describe(header: SpzHeader) -> str:
    kind = f"zstd, {header.streams} streams" if header.container == "zstd" else "gzip"
    return f"spz v{header.version} ({kind}, SH degree {header.sh_degree})"


def _check_header(h: SpzHeader, size: int, source) -> None:
    legacy_ok = 1 <= h.version <= 3
    if not (legacy_ok if h.container == "gzip" else h.version == 4):
        where = "a gzip stream" if h.container == "gzip" else "an NGSP header"
        raise InputError(source, f"unsupported spz version {h.version} in {where} (supported: 1-3 gzip, 4 zstd)")
    if h.sh_degree not in _SH_DIM:
        raise InputError(source, f"spz SH degree {h.sh_degree} is not valid (0-4)")
    if h.sh_degree == 4:
        raise InputError(source, "spz SH degree 4 is not supported (the harness holds SH degrees 0-3)")
    if h.points == 0:
        raise InputError(source, "spz header declares 0 points (an empty spz, which the reference loader rejects)")
    if sum(h.stream_sizes()) > size * _MAX_RATIO:
        raise InputError(source, f"spz header declares {h.points:,} points, impossible for a {size:,}-byte file "
                                 "(corrupt header or truncated file)")


def _inflate(data: bytes, size: int, source) -> bytes:
    """At most ``size`` bytes of the gzip stream ``data`` (never more: a bomb stops here)."""
    try:
        return zlib.decompressobj(16 + zlib.MAX_WBITS).decompress(data, size)
    except zlib.error as err:
        raise InputError(source, f"corrupt gzip data in spz file ({err})") from None


def _legacy_streams(data: bytes, h: SpzHeader, source) -> tuple[list[bytes], bytes]:
    sizes = h.stream_sizes()
    total = _LEGACY.size + sum(sizes)
    cap = total + (_MAX_TRAILING_EXTENSION_BYTES if h.flags & 2 else 0)
    raw = _inflate(data, cap, source)
    if len(raw) < total:
        raise InputError(source, f"truncated spz: {h.points:,} points need {total:,} decompressed bytes, "
                                 f"the gzip stream holds {len(raw):,}")
    offsets = np.cumsum([_LEGACY.size] + sizes)
    return [raw[a:b] for a, b in zip(offsets[:-1], offsets[1:])], raw[total:] if h.flags & 2 else b""


def _zstd_streams(data: bytes, h: SpzHeader, source) -> tuple[list[bytes], bytes]:
    sizes = h.stream_sizes()
    wanted = [s for s in sizes if s]
    toc = h.toc_offset
    if h.streams != len(wanted):
        raise InputError(source, f"spz v4 header lists {h.streams} streams; {h.points:,} points of SH degree "
                                 f"{h.sh_degree} need {len(wanted)}")
    if toc < _V4.size or toc + 16 * h.streams > len(data):
        raise InputError(source, f"spz v4 table of contents at byte {toc} lies outside the {len(data):,}-byte file")
    entries = [struct.unpack_from("<QQ", data, toc + 16 * i) for i in range(h.streams)]
    start = toc + 16 * h.streams
    if any(u != w for (_, u), w in zip(entries, wanted)):
        raise InputError(source, "spz v4 stream sizes do not match the point count in the header")
    if sum(c for c, _ in entries) != len(data) - start:
        raise InputError(source, f"spz v4 compressed streams add up to {sum(c for c, _ in entries):,} bytes; "
                                 f"the file holds {len(data) - start:,} after the table (truncated or corrupt)")
    try:
        import zstandard
    except ImportError:  # pragma: no cover - a declared dependency
        raise InputError(source, "reading spz v4 needs the 'zstandard' package") from None
    out = []
    for compressed, size in entries:
        frame = memoryview(data)[start:start + compressed]
        start += compressed
        try:
            with zstandard.ZstdDecompressor().stream_reader(frame) as reader:
                chunk = reader.read(size + 1)  # bounded: never more than the header implies
        except zstandard.ZstdError as err:
            raise InputError(source, f"corrupt zstd stream in spz v4 file ({err})") from None
        if len(chunk) != size:
            raise InputError(source, f"spz v4 stream decompresses to {len(chunk):,} bytes, its table says {size:,}")
        out.append(chunk)
    streams = iter(out)
    return [next(streams) if s else b"" for s in sizes], data[_V4.size:toc] if h.flags & 2 else b""


def _stored_system(extensions: bytes) -> int | None:
    """The CoordinateSystem stated by an SPZ_ADOBE_coordinate_system record, if any.

    Records are ``u32 type | u32 length | payload``; like the reference reader this stops at the
    first record that does not fit and skips unknown types.
    """
    pos = 0
    while pos + 8 <= len(extensions):
        kind, length = struct.unpack_from("<II", extensions, pos)
        if pos + 8 + length > len(extensions):
            break
        if kind == _COORDINATE_SYSTEM_RECORD and length >= 4:
            value = struct.unpack_from("<I", extensions, pos + 8)[0]
            if value <= 16:
                return value or SYSTEMS["RUB"]  # UNSPECIFIED in the record means RUB (resolve())
        pos += 8 + length
    return None


def _axis_signs(system: int, source) -> np.ndarray:
    """(sx, sy, sz) taking a standard-family system to PLY's RDF (``axesMatch``)."""
    if system not in _SYSTEM_NAMES:
        raise InputError(source, f"spz coordinate system {system} permutes axes; only LDB..RUF are supported")
    bits, rdf = system - 1, SYSTEMS["RDF"] - 1
    return np.array([1.0 if (bits >> i) & 1 == (rdf >> i) & 1 else -1.0 for i in range(3)])


def _flip_sh(s: np.ndarray) -> np.ndarray:
    x, y, z = s
    return np.array([y, z, x, x * y, y * z, 1, x * z, 1, y, x * y * z, y, z, x, z, x])


def _decode(streams: list[bytes], h: SpzHeader) -> tuple[np.ndarray, ...]:
    n, dim = h.points, _SH_DIM[h.sh_degree]
    pos, alpha, colour, scale, rot, sh = (np.frombuffer(s, np.uint8) for s in streams)
    if h.version == 1:
        means = pos.view("<f2").reshape(n, 3).astype(np.float64)
    else:
        b = pos.reshape(n, 3, 3).astype(np.int32)
        fixed = b[..., 0] | (b[..., 1] << 8) | (b[..., 2] << 16)
        means = np.where(fixed & 0x800000, fixed - (1 << 24), fixed) * 2.0 ** -h.fractional_bits
    if h.version >= 3:
        word = rot.view("<u4").astype(np.uint32)
        fields = np.stack([(word >> np.uint32(s)) & np.uint32(1023) for s in (20, 10, 0)], 1)
        mag = (fields & 511).astype(np.float64) * (np.sqrt(0.5) / 511.0)
        xyzw = smallest_three(word >> np.uint32(30), np.where(fields & 512, -mag, mag))
    else:
        xyz = rot.reshape(n, 3).astype(np.float64) / 127.5 - 1.0
        xyzw = np.concatenate([xyz, np.sqrt(np.maximum(0.0, 1.0 - (xyz * xyz).sum(1)))[:, None]], 1)
    return (means, _SCALE_OF_BYTE[scale.reshape(n, 3)], xyzw, LOGIT_OF_ALPHA_BYTE[alpha],
            _DC_OF_BYTE[colour.reshape(n, 3)], _SH_OF_BYTE[sh.reshape(n, dim, 3)])


def read_spz(path: str | Path, axes: str = "auto") -> GaussianScene:
    """Read an spz file. ``axes``: "auto" (the stored coordinate-system record, else PLY axes),
    "ply", or a standard-family system name (e.g. "RUB") the data is stored in."""
    from harness.io.safe import read_bytes

    path = Path(path)
    data = read_bytes(path, "scene", ".spz file")
    h = probe(data[:PROBE_BYTES])
    if h is None:
        raise InputError(path, "not an spz file (no NGSP header, plain or gzip-compressed)")
    _check_header(h, len(data), path)
    streams, extensions = (_legacy_streams if h.container == "gzip" else _zstd_streams)(data, h, path)
    means, scales_log, xyzw, opacity_logit, sh_dc, sh_rest = _decode(streams, h)
    if axes == "auto":
        system = _stored_system(extensions) or SYSTEMS["RDF"]
    else:
        system = SYSTEMS.get("RDF" if axes.lower() == "ply" else axes.upper())
        if system is None:
            raise InputError(path, f"unknown spz axes {axes!r}; use auto, ply or one of {', '.join(SYSTEMS)}")
    if system != SYSTEMS["RDF"]:
        s = _axis_signs(system, path)
        means = means * s
        xyzw = xyzw * np.array([s[1] * s[2], s[0] * s[2], s[0] * s[1], 1.0])
        sh_rest = sh_rest * _flip_sh(s)[: sh_rest.shape[1], None].astype(np.float32)
    return GaussianScene.from_arrays(means, scales_log, xyzw_to_wxyz(xyzw), opacity_logit, sh_dc, sh_rest)
