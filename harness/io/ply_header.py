"""The ``.ply`` header: ``format`` (ascii / binary_little_endian / binary_big_endian), ``element``,
``property``, ``comment`` (before ``format``: the preamble, where MPEG captures keep their cameras) and
``obj_info`` lines, parsed with bounds on lines, line length and properties before anything is allocated
from them. :mod:`harness.io.ply` reads the element data it describes."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from harness.core.errors import InputError
from harness.io.safe import open_regular

PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}
ENDIAN = {"binary_little_endian": "<", "binary_big_endian": ">", "ascii": "<"}
_MAX_HEADER_LINES = 100_000  # comments included (an MPEG capture header holds a few hundred camera lines)
#: properties of one element: a 3DGS vertex has 17..62; a header of more is refused before any
#: structured dtype of that many fields is built
_MAX_PROPERTIES = 4096
_MAX_HEADER_LINE = 1 << 20  # bytes per header line (a camera comment is ~400)


@dataclass
class PlyElement:
    name: str
    count: int
    properties: list[tuple[str, str]]  # (name, numpy type code) ; list properties use "list"


@dataclass
class PlyHeader:
    format: str
    elements: list[PlyElement]
    comments: list[str] = field(default_factory=list)   # after the `format` line
    data_offset: int = 0
    preamble: list[str] = field(default_factory=list)   # comments before the `format` line (MPEG cameras)

    def element(self, name: str) -> PlyElement | None:
        return next((e for e in self.elements if e.name == name), None)


def read_ply_header(path: str | Path) -> PlyHeader:
    """Parse the header; ``data_offset`` is the byte where the element data starts."""
    path = Path(path)
    elements: list[PlyElement] = []
    comments: list[str] = []
    preamble: list[str] = []
    declared: dict[int, set[str]] = {}  # property names per element
    fmt = None
    with open_regular(path, "scene", "PLY file") as f:
        if f.readline(16).strip() != b"ply":
            raise InputError(path, "not a PLY file (first line is not 'ply')")
        for lineno in range(2, _MAX_HEADER_LINES):
            raw = f.readline(_MAX_HEADER_LINE)
            if not raw.endswith(b"\n"):  # EOF, possibly in the middle of a line
                if len(raw) >= _MAX_HEADER_LINE:
                    raise InputError(path, f"PLY header line {lineno} is longer than {_MAX_HEADER_LINE} bytes")
                raise InputError(path, "PLY header has no 'end_header' line (truncated file?)")
            try:
                line = raw.decode("ascii").strip()
            except UnicodeDecodeError:
                raise InputError(path, f"PLY header line {lineno} is not ASCII text") from None
            words = line.split()
            if not words:
                continue
            key = words[0]
            if key == "end_header":
                break
            if key == "format":
                if len(words) != 3 or words[1] not in ENDIAN:
                    raise InputError(path, f"unsupported PLY format line {line!r}")
                fmt = words[1]
            elif key in ("comment", "obj_info"):
                (comments if fmt else preamble).append(line[len(key):].strip() if key == "comment" else line)
            elif key == "element":
                if len(words) != 3 or not words[2].isdigit():
                    raise InputError(path, f"bad PLY element line {line!r}")
                elements.append(PlyElement(words[1], int(words[2]), []))
            elif key == "property":
                if not elements:
                    raise InputError(path, f"PLY property before any element: {line!r}")
                props = elements[-1].properties
                if len(props) >= _MAX_PROPERTIES:
                    raise InputError(path, f"PLY element {elements[-1].name!r} declares more than "
                                           f"{_MAX_PROPERTIES:,} properties")
                if len(words) == 5 and words[1] == "list":
                    props.append((words[4], "list"))
                elif len(words) == 3 and words[1] in PLY_TYPES:
                    names = declared.setdefault(len(elements), set())  # a set: linear in the header
                    if words[2] in names:
                        raise InputError(path, f"PLY property {words[2]!r} is declared twice")
                    names.add(words[2])
                    props.append((words[2], PLY_TYPES[words[1]]))
                else:
                    raise InputError(path, f"bad PLY property line {line!r}")
            else:
                raise InputError(path, f"unknown PLY header keyword {key!r}")
        else:
            raise InputError(path, f"PLY header has more than {_MAX_HEADER_LINES:,} lines without 'end_header'")
        offset = f.tell()
    if fmt is None:
        raise InputError(path, "PLY header has no 'format' line")
    return PlyHeader(fmt, elements, comments, offset, preamble)
