"""mkkellogg GaussianSplats3D ``.ksplat`` (compression levels 0, 1, 2): probe and reader.

Layout (GaussianSplats3D ``src/loaders/SplatBuffer.js`` ``parseHeader``, ``parseSectionHeaders``,
``CompressionLevels``, ``writeSplatDataToSectionBuffer``, commit eb2fc45; cross-checked with
splat-transform ``src/lib/readers/read-ksplat.ts`` @8d6b801). Little-endian, no magic number:

* main header, 4096 bytes: ``u8 versionMajor (0) | u8 versionMinor (≥ 1) | 2 zero bytes |
  u32 maxSectionCount | u32 sectionCount | u32 maxSplatCount | u32 splatCount |
  u16 compressionLevel @20 | f32 sceneCenter[3] @24 | f32 minSH @36 | f32 maxSH @40``
  (minSH/maxSH 0 mean ∓1.5).
* ``maxSectionCount`` section headers of 1024 bytes: ``u32 splatCount | u32 maxSplatCount |
  u32 bucketSize | u32 bucketCount | f32 bucketBlockSize | u16 bucketStorageSizeBytes @20 |
  u32 compressionScaleRange @24 (0: level default) | u32 storageSize | u32 fullBucketCount @32 |
  u32 partiallyFilledBucketCount @36 | u16 shDegree @40``.
* then per section: ``u32 partial bucket lengths[partial] | f32 bucket centres[bucketCount][3] |
  maxSplatCount records``. Section sizes follow from these fields (``storageSize`` is not trusted:
  gaussforge writes 0); their sum must be the file size.

Records: level 0 ``f32 centre[3] | f32 scale[3] | f32 rot[4] | u8 rgba[4] | f32 sh[c]``; levels 1-2
``u16 centre[3] | f16 scale[3] | f16 rot[4] | u8 rgba[4] | sh[c]`` (f16 at level 1, u8 at level 2),
``c = 0, 9, 24, 45`` for SH degree 0-3 (GaussianSplats3D writes ≤ 2; degree 3 uses splat-transform's
extension of the band layout).

Decoding:

* centre (levels 1-2): ``(u16 − r)·(blockSize/2/r) + bucketCentre[b]``, ``r = compressionScaleRange``
  or 32767; splat i is in bucket ``i // bucketSize`` among the full buckets, then in the partial
  buckets in order, each holding its listed length.
* scale is *linear*: ``scales_log = log(scale)``. Zero, which the writer's truncating float16
  conversion produces for scales below 2⁻²⁴ (float32: 2⁻¹⁴⁹), decodes to the log of that smallest
  positive value (splat-transform uses −10) so the splat stays tiny and finite.
* rotation is (w, x, y, z) (not renormalised). ``f_dc = (byte/255 − 0.5)/SH_C0``; alpha byte is linear
  opacity (:mod:`harness.io.codecs`; the writer floors and drops splats whose byte is 0).
* SH component i of a record -> (channel, coefficient): band 1 ``i < 9: (i // 3, i % 3)``,
  band 2 ``i < 24: ((i − 9) // 5, 3 + (i − 9) % 5)``, band 3 ``((i − 24) // 7, 8 + (i − 24) % 7)``.
  Level 2: ``byte/255·(maxSH − minSH) + minSH``.

The writer reorders splats (distance sort, then buckets); files are read in file order.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from harness.core.errors import InputError
from harness.core.scene import SH_C0, SH_REST_COUNT, GaussianScene
from harness.io.codecs import LOGIT_OF_ALPHA_BYTE, log_of_linear
from harness.io.sog import concat_scenes

HEADER_BYTES, SECTION_BYTES = 4096, 1024
_MAIN = np.dtype({"names": ["major", "minor", "pad", "max_sections", "sections", "max_splats", "splats", "level",
                            "sh_min", "sh_max"],
                  "formats": ["u1", "u1", "<u2", "<u4", "<u4", "<u4", "<u4", "<u2", "<f4", "<f4"],
                  "offsets": [0, 1, 2, 4, 8, 12, 16, 20, 36, 40], "itemsize": HEADER_BYTES})
_SECTION = np.dtype({"names": ["splats", "max_splats", "bucket_size", "buckets", "block", "bucket_bytes",
                               "scale_range", "full", "partial", "sh_degree"],
                     "formats": ["<u4", "<u4", "<u4", "<u4", "<f4", "<u2", "<u4", "<u4", "<u4", "<u2"],
                     "offsets": [0, 4, 8, 12, 16, 20, 24, 32, 36, 40], "itemsize": SECTION_BYTES})
#: per level: (centre, scale/rotation, SH) storage types
_TYPES = {0: ("<f4", "<f4", "<f4"), 1: ("<u2", "<f2", "<f2"), 2: ("<u2", "<f2", "u1")}
_SH_COMPONENTS = {0: 0, 1: 9, 2: 24, 3: 45}
_SMALLEST = {"<f4": np.log(2.0 ** -149), "<f2": np.log(2.0 ** -24)}


def _record_dtype(level: int, sh_degree: int) -> np.dtype:
    centre, half, sh = _TYPES[level]
    fields = [("centre", centre, (3,)), ("scale", half, (3,)), ("rot", half, (4,)), ("rgba", "u1", (4,))]
    if sh_degree:
        fields.append(("sh", sh, (_SH_COMPONENTS[sh_degree],)))
    return np.dtype(fields)


@dataclass(frozen=True)
class KsplatHeader:
    main: np.void             # one _MAIN row
    sections: np.ndarray      # _SECTION rows (maxSectionCount of them)
    size: int                 # bytes the headers account for

    @property
    def level(self) -> int:
        return int(self.main["level"])

    @property
    def sh_degree(self) -> int:
        used = self.sections["sh_degree"][self.sections["splats"] > 0]
        return int(used.max()) if len(used) else 0


def _section_bytes(level: int, sec: np.ndarray) -> np.ndarray:
    """Bytes of each section's data (bucket tables + records), int64."""
    comps = np.array([_SH_COMPONENTS.get(int(d), 0) for d in sec["sh_degree"]], np.int64)
    centre, half, sh = (np.dtype(t).itemsize for t in _TYPES[level])
    per_splat = 3 * centre + 7 * half + 4 + comps * sh
    return sec["partial"].astype(np.int64) * 4 + sec["bucket_bytes"].astype(np.int64) * sec["buckets"] \
        + per_splat * sec["max_splats"]


def _fromfile(path: Path, dtype, count: int, offset: int = 0) -> np.ndarray:
    """``np.fromfile`` through the bounded reader (a regular file, opened without blocking)."""
    from harness.io.safe import open_regular

    with open_regular(path, "scene", ".ksplat file") as f:
        f.seek(offset)
        return np.fromfile(f, dtype, count=count)


def parse_headers(path: Path, size: int) -> KsplatHeader:
    """The main and section headers; InputError naming what does not fit a ksplat."""
    if size < HEADER_BYTES:
        raise InputError(path, f"a ksplat starts with a 4096-byte header; the file has {size:,} bytes")
    main = _fromfile(path, _MAIN, count=1)[0]
    if main["major"] != 0 or main["minor"] < 1 or main["pad"] != 0:
        raise InputError(path, f"ksplat version {main['major']}.{main['minor']} is not supported (0.1 and later 0.x)")
    if main["level"] > 2:
        raise InputError(path, f"ksplat compression level {main['level']} is not supported (0-2)")
    count = int(main["max_sections"])
    if count < 1 or HEADER_BYTES + count * SECTION_BYTES > size:
        raise InputError(path, f"ksplat header lists {count:,} sections; their headers need "
                               f"{HEADER_BYTES + count * SECTION_BYTES:,} bytes, the file has {size:,}")
    sections = _fromfile(path, _SECTION, count=count, offset=HEADER_BYTES)
    total = HEADER_BYTES + count * SECTION_BYTES + int(_section_bytes(int(main["level"]), sections).sum())
    return KsplatHeader(main, sections, total)


def probe(path: Path, size: int) -> KsplatHeader | None:
    """The headers when the file starts like a ksplat (version 0.x ≥ 0.1, level 0-2), else None."""
    try:
        return parse_headers(path, size)
    except InputError:
        return None


def looks_like_ksplat(head: bytes) -> bool:
    """The first bytes every ksplat writer produces: version 0.1+ then two zero bytes."""
    return len(head) >= 4 and head[0] == 0 and head[1] >= 1 and head[2:4] == b"\0\0"


def describe(h: KsplatHeader) -> str:
    n = len(h.sections)
    return (f"ksplat level {h.level} (v{h.main['major']}.{h.main['minor']}, {n} section{'s' * (n != 1)}, "
            f"SH degree {h.sh_degree})")


def _validate(h: KsplatHeader, size: int, source) -> None:
    sec = h.sections
    bad = [int(d) for d in sec["sh_degree"] if d not in _SH_COMPONENTS]
    if bad:
        raise InputError(source, f"ksplat section has SH degree {bad[0]}; expected 0-3")
    if h.level and ((sec["buckets"] > 0) & (sec["bucket_bytes"] != 12)).any():
        raise InputError(source, "ksplat bucket entries must be 12 bytes (3 floats)")
    if h.size != size:
        raise InputError(source, f"ksplat headers describe {h.size:,} bytes but the file has {size:,} "
                                 "(truncated file or corrupt header)")
    if (sec["splats"] > sec["max_splats"]).any():
        raise InputError(source, "ksplat section holds more splats than its capacity")
    if int(sec["splats"].astype(np.int64).sum()) != int(h.main["splats"]):
        raise InputError(source, f"ksplat header counts {int(h.main['splats']):,} splats, its sections "
                                 f"{int(sec['splats'].astype(np.int64).sum()):,}")


def _bucket_of(sec: np.void, lengths: np.ndarray, source) -> np.ndarray:
    """Bucket index of each of the section's splats."""
    n, size, full = int(sec["splats"]), int(sec["bucket_size"]), int(sec["full"])
    in_full = min(n, full * size)
    index = np.empty(n, np.int64)
    if in_full:
        index[:in_full] = np.arange(in_full) // size
    rest = n - in_full
    ends = np.cumsum(lengths.astype(np.int64))
    if rest and (not len(ends) or ends[-1] < rest):
        raise InputError(source, f"ksplat buckets hold fewer splats than the section's {n:,}")
    index[in_full:] = full + np.searchsorted(ends, np.arange(rest), side="right")
    if n and (index.max() >= int(sec["buckets"])):
        raise InputError(source, "ksplat splat refers to a bucket beyond the section's bucket table")
    return index


def _sh_slots(degree: int) -> tuple[np.ndarray, np.ndarray]:
    """(coefficient, channel) of each ksplat SH component, band by band, channel-major in a band."""
    coef, chan = [], []
    for first, width in ((0, 3), (3, 5), (8, 7))[:degree]:
        for c in range(3):
            coef += range(first, first + width)
            chan += [c] * width
    return np.array(coef, np.int64), np.array(chan, np.int64)


def _read_section(path: Path, h: KsplatHeader, sec: np.void, offset: int, sh_range, source) -> GaussianScene:
    level, degree = h.level, int(sec["sh_degree"])
    n, partial, buckets = int(sec["splats"]), int(sec["partial"]), int(sec["buckets"])
    rec_type = _record_dtype(level, degree)
    data_at = offset + partial * 4 + int(sec["bucket_bytes"]) * buckets
    rec = _fromfile(path, rec_type, count=n, offset=data_at)
    if level:
        lengths = _fromfile(path, "<u4", count=partial, offset=offset)
        centres = _fromfile(path, "<f4", count=3 * buckets, offset=offset + partial * 4).reshape(-1, 3)
        r = int(sec["scale_range"]) or 32767
        step = float(sec["block"]) / 2.0 / r
        means = (rec["centre"].astype(np.float64) - r) * step + centres[_bucket_of(sec, lengths, source)]
    else:
        means = rec["centre"]
    scale = rec["scale"].astype(np.float64)
    scales_log = np.where(scale == 0, _SMALLEST[_TYPES[level][1]], log_of_linear(scale))
    rgba = rec["rgba"]
    sh_rest = np.zeros((n, SH_REST_COUNT[h.sh_degree], 3), np.float32)
    if degree:
        values = rec["sh"].astype(np.float64)
        if level == 2:
            lo, hi = sh_range
            values = values / 255.0 * (hi - lo) + lo
        coef, chan = _sh_slots(degree)
        sh_rest[:, coef, chan] = values
    return GaussianScene.from_arrays(means, scales_log, rec["rot"], LOGIT_OF_ALPHA_BYTE[rgba[:, 3]],
                                     (rgba[:, :3] / 255.0 - 0.5) / SH_C0, sh_rest)


def read_ksplat(path: str | Path) -> GaussianScene:
    """Read a ``.ksplat`` file (levels 0-2, every section, in file order)."""
    from harness.io.safe import check_regular

    path = Path(path)
    size = check_regular(path, "scene", ".ksplat file").st_size
    h = parse_headers(path, size)
    _validate(h, size, path)
    lo, hi = (float(h.main[k]) for k in ("sh_min", "sh_max"))
    sh_range = (lo if lo and np.isfinite(lo) else -1.5, hi if hi and np.isfinite(hi) else 1.5)
    offset = HEADER_BYTES + len(h.sections) * SECTION_BYTES
    parts = []
    for sec, nbytes in zip(h.sections, _section_bytes(h.level, h.sections)):
        if sec["splats"]:
            parts.append(_read_section(path, h, sec, offset, sh_range, path))
        offset += int(nbytes)
    if not parts:
        raise InputError(path, "ksplat file holds no splats")
    return parts[0] if len(parts) == 1 else concat_scenes(parts)
