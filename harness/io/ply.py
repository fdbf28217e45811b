"""INRIA 3DGS ``.ply``: reader by property name and binary little-endian writer.

Reading
    The header is parsed by :mod:`harness.io.ply_header` (``format`` ascii / binary_little_endian / binary_big_endian,
    ``element``, ``property``, ``comment``, ``obj_info``); the ``vertex`` element's rows are read
    with one ``np.fromfile`` (binary) or ``np.loadtxt`` (ascii) and then picked apart *by name*, so
    any property order works. Required: ``x y z f_dc_0..2 opacity scale_0..2 rot_0..3``; the SH
    degree follows from the ``f_rest_*`` count (0, 9, 24, 45 -> degree 0..3). The file stores
    ``f_rest`` channel-major, ``f_rest_{c*K + k}``, and the scene coefficient-major,
    ``sh_rest[:, k, c]``. Every other vertex property (``nx ny nz`` ...) lands in ``scene.extra`` in
    file order with its own dtype (byte order made native). Core properties stored as another
    numeric type (e.g. ``double``) are cast to float32. Elements before ``vertex`` are skipped (they
    must have fixed-size rows in a binary file); elements after it are ignored.

Writing
    Binary little-endian, the order of the original 3DGS ``save_ply``:
    ``x y z [nx ny nz] f_dc_0..2 f_rest_0.. opacity scale_0..2 rot_0..3`` then the remaining extras
    in their ``scene.extra`` order. Normals are written only when the scene carries them (the
    original writer always emits zero normals; adding them here would change the property set of a
    file that had none, and a pruned file must be the input minus rows). Every value is written
    with its own bytes, so writing ``read_ply(p).subset(keep)`` keeps each kept value bit-exact and
    read -> write -> read is the identity. Output goes to a temporary file that is renamed into
    place, so a failed write never leaves a partial file.

    Viewers that read by name (antimatter15, SuperSplat, gsplat.js ...) open any such file. SIBR's
    ``SIBR_gaussianViewer_app`` (the original 3DGS viewer) instead copies rows into a fixed struct
    (xyz, normal, 48 SH floats, opacity, scale, rot); ``sibr_layout=True`` writes exactly that: zero
    normals when absent, SH zero-padded to degree 3, no other extras.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from harness.core.errors import InputError
from harness.core.scene import SH_REST_COUNT, GaussianScene
from harness.io.files import atomic_write_chunks
from harness.io.ply_header import ENDIAN, PlyElement, PlyHeader, read_ply_header
from harness.io.safe import open_regular

_WRITE_TYPES = {"i1": "char", "u1": "uchar", "i2": "short", "u2": "ushort",
                "i4": "int", "u4": "uint", "f4": "float", "f8": "double"}
REQUIRED = ("x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity",
            "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3")
NORMALS = ("nx", "ny", "nz")
#: the 3DGS properties must be stored as float or double: integer bytes read as floats (or the
#: reverse) decode to garbage that no check downstream can tell from data
_FLOAT_TYPES = ("f4", "f8")


def _vertex_dtype(element: PlyElement, endian: str, path: Path) -> np.dtype:
    if any(t == "list" for _, t in element.properties):
        raise InputError(path, f"the {element.name} element has a list property; 3DGS files have none")
    return np.dtype([(name, endian + t) for name, t in element.properties])


def _fixed_size(el: PlyElement, endian: str) -> int | None:
    """Bytes of a binary element with fixed-size rows; None when it has list properties."""
    if any(t == "list" for _, t in el.properties):
        return None
    return el.count * np.dtype([(n, endian + t) for n, t in el.properties]).itemsize


def _short(path: Path, el: PlyElement, dtype: np.dtype, available: int) -> InputError:
    """The error for an element of which only ``available`` bytes are present."""
    name = f"{el.name!r}"
    rows, row = ("vertices", "vertex") if el.name == "vertex" else (f"{name} rows", f"{name} row")
    whole = max(available, 0) // dtype.itemsize
    if max(available, 0) % dtype.itemsize:
        return InputError(path, f"truncated: the data ends inside {row} {whole + 1} of {el.count} "
                                f"({max(available, 0)} of {el.count * dtype.itemsize} bytes present)")
    return InputError(path, f"header declares {el.count} {rows} but the file holds data for only {whole} "
                            "(truncated file or wrong count)")


def _check_size(path: Path, header: PlyHeader, sizes: list, file_size: int) -> None:
    """With every element of fixed size, the file must end exactly where the last one ends: too few
    bytes name the element (and row) where the data stops; trailing bytes are an error too."""
    endian = ENDIAN[header.format]
    expected = header.data_offset + sum(sizes)
    if file_size < expected:
        pos = header.data_offset
        for el, size in zip(header.elements, sizes):
            if file_size < pos + size:
                raise _short(path, el, _vertex_dtype(el, endian, path), file_size - pos)
            pos += size
    if file_size > expected:
        extra, last = file_size - expected, header.elements[-1] if header.elements else None
        if last is not None:
            itemsize = _vertex_dtype(last, endian, path).itemsize
            if itemsize and extra % itemsize == 0:
                raise InputError(path, f"header declares {last.count} {'vertices' if last.name == 'vertex' else 'rows'}"
                                       f" of {last.name!r} but the file holds data for "
                                       f"{last.count + extra // itemsize} (wrong count)")
        raise InputError(path, f"{extra} bytes after the last element (the header declares {expected} bytes "
                               "in all; wrong count or trailing garbage)")


def _read_binary(path: Path, header: PlyHeader, element: PlyElement) -> np.ndarray:
    """The rows of one element of a binary file (elements before it must have fixed-size rows). The
    file's size must be exactly what the header declares (:func:`_check_size`)."""
    endian = ENDIAN[header.format]
    sizes = [_fixed_size(el, endian) for el in header.elements]
    idx = header.elements.index(element)
    if None in sizes[:idx]:
        bad = header.elements[sizes[:idx].index(None)]
        raise InputError(path, f"element {bad.name!r} before {element.name!r} has list properties (unsupported)")
    offset = header.data_offset + sum(sizes[:idx])
    dtype = _vertex_dtype(element, endian, path)
    n = element.count
    with open_regular(path, "scene", "PLY file") as f:
        file_size = os_size(f)
        if None not in sizes:
            _check_size(path, header, sizes, file_size)
        elif file_size - offset < n * dtype.itemsize:
            raise _short(path, element, dtype, file_size - offset)
        if dtype.itemsize == 0:  # an element without properties (e.g. an empty compressed.ply 'sh')
            return np.zeros(n, dtype)
        f.seek(offset)
        table = np.fromfile(f, dtype=dtype, count=n)
    if len(table) != n:
        raise InputError(path, f"truncated while reading: {len(table)} of {n} rows of {element.name!r}")
    return table


def os_size(f) -> int:
    import os

    return os.fstat(f.fileno()).st_size


def read_binary_elements(path: str | Path, header: PlyHeader) -> dict[str, np.ndarray]:
    """Every element of a binary PLY as a structured array, by name (sizes checked first)."""
    path = Path(path)
    if header.format == "ascii":
        raise InputError(path, "expected a binary PLY, found format ascii")
    return {el.name: _read_binary(path, header, el) for el in header.elements}


def _read_ascii(path: Path, header: PlyHeader, vertex: PlyElement) -> np.ndarray:
    dtype = _vertex_dtype(vertex, "<", path)
    position = header.elements.index(vertex)
    skip = sum(el.count for el in header.elements[:position])
    last = position == len(header.elements) - 1
    with open_regular(path, "scene", "PLY file") as f:
        # every ascii row holds at least one character and one separator per property: a count the
        # file cannot possibly hold is rejected before reading (a huge count must not loop or exhaust memory)
        available = os_size(f) - header.data_offset
        if skip + vertex.count * 2 * len(vertex.properties) > available:
            raise InputError(path, f"header declares {vertex.count} vertices but the file is too short to "
                                   f"hold them (truncated file or wrong count)")
        f.seek(header.data_offset)
        for _ in range(skip):
            if not f.readline():
                raise InputError(path, "truncated: the file ends before the vertex element")
        lines = [f.readline() for _ in range(vertex.count)]
        rest = f.read(1 << 16) if last else b""
    rows = [ln for ln in lines if ln.strip()]
    if len(rows) < vertex.count:
        raise InputError(path, f"header declares {vertex.count} vertices but the file holds only "
                               f"{len(rows)} rows (truncated file or wrong count)")
    if rest.strip():
        extra = len([ln for ln in rest.splitlines() if ln.strip()])
        raise InputError(path, f"header declares {vertex.count} vertices but {extra}"
                               f"{'+' if len(rest) == 1 << 16 else ''} more non-empty lines follow (wrong count "
                               "or trailing garbage)")
    ncols = len(vertex.properties)
    try:
        values = np.loadtxt(rows, dtype=np.float64, ndmin=2) if rows else np.zeros((0, ncols))
    except ValueError as err:
        raise InputError(path, f"bad ascii vertex data: {err}") from None
    if values.shape[1] != ncols:
        raise InputError(path, f"ascii vertex rows have {values.shape[1]} values, header declares {ncols}")
    out = np.empty(vertex.count, dtype=dtype)
    for j, (name, code) in enumerate(vertex.properties):
        col = values[:, j]
        if code[0] in "iu":  # integer property: whole numbers within the type's range, nothing cast silently
            info = np.iinfo(code)
            bad = ~np.isfinite(col) | (col != np.round(col)) | (col < info.min) | (col > info.max)
            if bad.any():
                row = int(np.flatnonzero(bad)[0])
                raise InputError(path, f"ascii vertex {row}: property {name!r} ({code}) holds {float(col[row])!r}, "
                                       f"not an integer in [{info.min}, {info.max}]")
        out[name] = col
    return out


def _sh_rest_count(path: Path, names: list[str]) -> int:
    rest = [n for n in names if n.startswith("f_rest_")]
    m = len(rest)
    if m not in {3 * k for k in SH_REST_COUNT.values()}:
        raise InputError(path, f"found {m} f_rest_* properties; expected 0, 9, 24 or 45 (SH degree 0-3)")
    missing = sorted({f"f_rest_{i}" for i in range(m)} - set(rest))
    if missing:
        raise InputError(path, f"f_rest_* properties are not numbered 0..{m - 1} (missing {missing[0]})")
    return m // 3


def _float_matrix(table: np.ndarray) -> np.ndarray | None:
    """(N, P) view of rows made only of float32 properties (either byte order), else None."""
    fields = [table.dtype[n] for n in table.dtype.names]
    if fields and len(set(fields)) == 1 and fields[0].str[1:] == "f4" and table.dtype.itemsize == 4 * len(fields):
        return table.view(fields[0]).reshape(len(table), len(fields))
    return None


def _block(table: np.ndarray, mat: np.ndarray | None, names: list[str]) -> np.ndarray:
    """(N, len(names)) values of the named properties; a view when they are adjacent float32 columns."""
    if not names:
        return np.zeros((len(table), 0), np.float32)
    if mat is None:
        return np.stack([table[n] for n in names], axis=1)
    position = {n: i for i, n in enumerate(table.dtype.names)}
    idx = [position[n] for n in names]
    if idx == list(range(idx[0], idx[0] + len(idx))):
        return mat[:, idx[0]: idx[0] + len(idx)]  # slicing is a view; the caller's copy does the work once
    return mat[:, idx]


def table_to_scene(table: np.ndarray, path: str | Path) -> GaussianScene:
    """Build a scene from a structured array of vertex rows, by property name."""
    path = Path(path)
    names = list(table.dtype.names)
    missing = [n for n in REQUIRED if n not in names]
    if missing:
        raise InputError(path, f"missing required propert{'y' if len(missing) == 1 else 'ies'} "
                               f"{', '.join(missing)} (not a 3DGS splat PLY?)")
    k = _sh_rest_count(path, names)
    for name in REQUIRED + tuple(f"f_rest_{i}" for i in range(3 * k)):
        code = table.dtype[name].str[1:]
        if code not in _FLOAT_TYPES:
            raise InputError(path, f"property {name!r} is stored as {_WRITE_TYPES.get(code, code)}; the 3DGS "
                                   "properties must be float or double")
    n = len(table)
    mat = _float_matrix(table)
    f32 = lambda names: np.ascontiguousarray(_block(table, mat, names), dtype=np.float32)  # one copy each
    rest_names = [f"f_rest_{i}" for i in range(3 * k)]
    # channel-major f_rest_{c*K + k} -> coefficient-major [k, c], transposed during the copy
    rest = _block(table, mat, rest_names).reshape(n, 3, k).transpose(0, 2, 1)
    known = set(REQUIRED) | set(rest_names)
    extra = {name: table[name].astype(table.dtype[name].newbyteorder("="))  # a copy, native byte order
             for name in names if name not in known}
    return GaussianScene(
        means=f32(["x", "y", "z"]),
        sh_dc=f32([f"f_dc_{i}" for i in range(3)]),
        opacity_logit=f32(["opacity"]).reshape(n),
        scales_log=f32([f"scale_{i}" for i in range(3)]),
        quats=f32([f"rot_{i}" for i in range(4)]),
        sh_rest=np.ascontiguousarray(rest, dtype=np.float32),
        extra=extra,
    )


def read_ply_table(path: str | Path, header: PlyHeader | None = None) -> tuple[np.ndarray, PlyHeader]:
    """The raw ``vertex`` rows as a structured array (file dtypes), and the header."""
    path = Path(path)
    header = header or read_ply_header(path)
    vertex = header.element("vertex")
    if vertex is None:
        raise InputError(path, "PLY file has no 'vertex' element")
    reader = _read_ascii if header.format == "ascii" else _read_binary
    return reader(path, header, vertex), header


def read_ply(path: str | Path) -> GaussianScene:
    """Read an INRIA 3DGS ``.ply`` (any property order, ascii or binary) into a scene whose
    :class:`SceneMeta` holds the path and the header comments (before and after ``format``).

    A PlayCanvas ``compressed.ply`` (``chunk`` element, ``packed_*`` vertex properties) is decoded
    by :mod:`harness.io.compressed_ply`.
    """
    from harness.io import compressed_ply

    header = read_ply_header(path)
    if compressed_ply.is_compressed_ply(header):
        scene, fmt = compressed_ply.decode_compressed_ply(read_binary_elements(path, header), path), "compressed-ply"
    else:
        scene, fmt = table_to_scene(read_ply_table(path, header)[0], path), "ply"
    return scene.with_meta(source=str(path), format=fmt, preamble=tuple(header.preamble),
                           comments=tuple(header.comments))


# ---------------------------------------------------------------------- writing
def ply_layout(scene: GaussianScene) -> list[tuple[str, np.dtype]]:
    """Output properties (name, little-endian dtype) in the INRIA order, extras placed as documented."""
    f4 = np.dtype("<f4")
    k = scene.sh_rest.shape[1]
    normals = [n for n in NORMALS if n in scene.extra]
    others = [n for n in scene.extra if n not in normals]
    layout = [(n, f4) for n in ("x", "y", "z")]
    layout += [(n, scene.extra[n].dtype.newbyteorder("<")) for n in normals]
    layout += [(f"f_dc_{i}", f4) for i in range(3)]
    layout += [(f"f_rest_{i}", f4) for i in range(3 * k)]
    layout += [("opacity", f4)] + [(f"scale_{i}", f4) for i in range(3)] + [(f"rot_{i}", f4) for i in range(4)]
    layout += [(n, scene.extra[n].dtype.newbyteorder("<")) for n in others]
    for name, arr in scene.extra.items():
        if arr.ndim != 1 or arr.dtype.str[1:] not in _WRITE_TYPES:
            raise ValueError(f"extra property {name!r} ({arr.dtype}, shape {arr.shape}) "
                             "cannot be stored as a PLY vertex property")
    return layout


def ply_header_bytes(layout: list[tuple[str, np.dtype]], count: int, comments=(), preamble=()) -> bytes:
    lines = ["ply"] + [f"comment {c}" for c in preamble] + ["format binary_little_endian 1.0"]
    lines += [f"comment {c}" for c in comments]
    lines.append(f"element vertex {count}")
    lines += [f"property {_WRITE_TYPES[dt.str[1:]]} {name}" for name, dt in layout]
    lines.append("end_header")
    return ("\n".join(lines) + "\n").encode("ascii")


def scene_to_table(scene: GaussianScene) -> np.ndarray:
    """The scene as a structured array in the output layout (the inverse of :func:`table_to_scene`)."""
    layout = ply_layout(scene)
    n, k = len(scene), scene.sh_rest.shape[1]
    table = np.empty(n, dtype=np.dtype(layout))
    position = {name: i for i, (name, _) in enumerate(layout)}
    groups = [("x", scene.means), ("f_dc_0", scene.sh_dc), ("opacity", scene.opacity_logit[:, None]),
              ("scale_0", scene.scales_log), ("rot_0", scene.quats),
              ("f_rest_0", scene.sh_rest.transpose(0, 2, 1).reshape(n, 3 * k))]  # [k, c] -> f_rest_{c*K + k}
    groups += [(name, values[:, None]) for name, values in scene.extra.items()]
    mat = _float_matrix(table)
    for first, values in groups:
        if values.shape[1] == 0:
            continue
        start = position[first]
        if mat is not None:  # all-float32 rows: assign whole column blocks
            mat[:, start: start + values.shape[1]] = values
        else:
            for j in range(values.shape[1]):
                table[layout[start + j][0]] = values[:, j]
    return table


def sibr_compatible(scene: GaussianScene) -> GaussianScene:
    """The scene in SIBR's fixed layout: normals (zero when absent), SH degree 3, no other extras."""
    n, k = len(scene), scene.sh_rest.shape[1]
    rest = np.zeros((n, SH_REST_COUNT[3], 3), np.float32)
    rest[:, :k] = scene.sh_rest
    normals = {name: scene.extra.get(name, np.zeros(n, np.float32)).astype(np.float32) for name in NORMALS}
    return GaussianScene(scene.means, scene.scales_log, scene.quats, scene.opacity_logit, scene.sh_dc, rest, normals)


def write_ply(scene: GaussianScene, path: str | Path, *, comments=None, preamble=None,
              sibr_layout: bool = False) -> None:
    """Write ``scene`` as a binary little-endian INRIA ``.ply`` (atomically); see the module docstring.

    Header comments default to the scene's own (``scene.meta``), each where it stood: the preamble
    before the ``format`` line, the rest after it — except MPEG ``camera_position`` lines, which
    always go before ``format`` (:func:`harness.io.gscameras.split_preamble`)."""
    from harness.io.gscameras import split_preamble

    comments = scene.meta.comments if comments is None else comments
    preamble = scene.meta.preamble if preamble is None else preamble
    preamble, comments = split_preamble(preamble, comments)  # MPEG camera lines always before `format`
    if sibr_layout:
        scene = sibr_compatible(scene)
    table = scene_to_table(scene)
    header = ply_header_bytes(ply_layout(scene), len(scene), comments, preamble)
    atomic_write_chunks(path, [header, table])
