"""Which scene format a path holds, by content first (magic bytes, headers), then by name.

=================  ===========================================================================
kind               recognised by
=================  ===========================================================================
ply                first line ``ply``; the vertex element has no ``packed_*`` properties
compressed-ply     first line ``ply``; a ``chunk`` element and ``packed_position`` (PlayCanvas)
spz                ``NGSP`` (v4, zstd) or a gzip stream that inflates to an ``NGSP`` header (v1-3)
ksplat             no magic: a 4096-byte header (version 0.1+, level 0-2) whose section headers
                   account for exactly the file's size; or a ``.ksplat`` file starting 00 01+ 00 00
sog                a folder with ``meta.json`` / ``lod-meta.json``, either JSON file, a ``.sog`` zip
splat              no magic: the ``.splat`` extension (antimatter15 32-byte records)
=================  ===========================================================================

Anything else is ``unsupported format: <what it looks like>`` (glTF binary, gzip or zstd data
that is not spz, images, archives, text, or a hex peek at the first bytes), never a guess.
"""

from __future__ import annotations

import json
import struct
from dataclasses import dataclass
from pathlib import Path

from harness.core.errors import InputError
from harness.io.safe import check_regular, open_regular

_PEEK = 64


@dataclass(frozen=True)
class Detected:
    kind: str  # a registered format (harness.io.formats): "ply" | "compressed-ply" | "spz" | "ksplat" | ...
    name: str  # what `harness info` prints


def detect(path: Path) -> Detected:
    """The format of ``path`` (a file or SOG folder): the first registered format
    (:mod:`harness.io.formats`, in registration order) that recognises it; InputError when none does."""
    from harness.io.formats import FORMATS, Probe

    if path.is_dir():
        probe = Probe(path, None, None)
    else:
        size = check_regular(path, "scene", "scene file").st_size  # FIFOs, devices, huge files refused first
        with open_regular(path, "scene", "scene file") as f:
            probe = Probe(path, f.read(_PEEK), size)
    for fmt in FORMATS:
        name = fmt.detect(probe)
        if name is not None:
            return Detected(fmt.kind, name)
    if probe.is_dir:
        raise InputError(path, "is a folder without lod-meta.json or meta.json (not a SOG scene)")
    raise InputError(path, f"unsupported format: {looks_like(path, probe.head, probe.size)}")


def _read(path: Path, count: int) -> bytes:
    with open_regular(path, "scene", "scene file") as f:
        return f.read(count)


def _glb(path: Path, size: int) -> str:
    """What a glTF binary holds, from its JSON chunk (bounded read)."""
    data = _read(path, min(size, 20 + (1 << 24)))
    extensions = set()
    if len(data) >= 20 and data[16:20] == b"JSON":
        length = struct.unpack_from("<I", data, 12)[0]
        try:
            doc = json.loads(data[20:20 + length])
            extensions = set(doc.get("extensionsUsed", [])) if isinstance(doc, dict) else set()
        except (UnicodeDecodeError, json.JSONDecodeError, TypeError):
            pass
    splats = sorted(e for e in extensions if isinstance(e, str) and e.startswith("KHR_gaussian_splatting"))
    if splats:
        return (f"a glTF binary (.glb) with {', '.join(splats)} splats, which the harness does not read; "
                "export the scene as .ply, .compressed.ply, .spz or .splat instead")
    return "a glTF binary (.glb) without gaussian splats (a mesh or scene)"


_MAGICS = [
    (b"\x89PNG\r\n\x1a\n", "a PNG image"),
    (b"\xff\xd8\xff", "a JPEG image"),
    (b"GIF8", "a GIF image"),
    (b"%PDF", "a PDF document"),
    (b"\x28\xb5\x2f\xfd", "zstd-compressed data that is not spz (spz v4 starts with NGSP)"),
    (b"\x1f\x8b", "a gzip file that is not spz (it does not inflate to an NGSP header)"),
    (b"PK\x03\x04", "a zip archive without meta.json (not a SOG bundle)"),
    (b"7z\xbc\xaf\x27\x1c", "a 7-zip archive"),
    (b"NGSP", "an spz header too short to hold its fields (truncated file)"),
]


def looks_like(path: Path, head: bytes, size: int) -> str:
    """A short description of bytes the harness cannot read."""
    if size == 0:
        return "empty file"
    if head[:4] == b"glTF":
        return _glb(path, size)
    if head[:4] == b"RIFF" and head[8:12] == b"WEBP":
        return "a WebP image"
    for magic, what in _MAGICS:
        if head.startswith(magic):
            return what
    try:
        text = head.decode("utf-8")
    except UnicodeDecodeError as err:  # a character cut at the end of the peek is still text
        text = head[:err.start].decode("utf-8") if err.start >= len(head) - 3 else None
    if text is not None and all(c.isprintable() or c in "\r\n\t" for c in text):
        first = text.splitlines()[0][:24] if text.strip() else ""
        if text.lstrip().startswith(("{", "[")):
            return "JSON text (not a SOG meta.json; SOG metadata files are named meta.json or lod-meta.json)"
        return f"text that is not a PLY header (starts {first!r})"
    peek = head[:8]
    shown = "".join(chr(b) if 32 <= b < 127 else "." for b in peek)
    return f"unrecognised binary data (first bytes {peek.hex(' ')} '{shown}', {size:,} bytes)"
