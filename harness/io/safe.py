"""Bounded, safe reads: every reader opens its files through here.

Rules:

* **Regular files only.** A path is ``stat``-ed before it is opened and FIFOs, sockets, character
  and block devices (``/dev/zero``), and folders are refused with one line. The file is then opened
  with ``O_NONBLOCK`` (opening a FIFO swapped in after the ``stat`` cannot block) and ``fstat``-ed
  again, so what is read is the regular file that was checked.
* **A size cap per kind of file** (:data:`LIMITS`), checked against the size on disk before any
  byte is read: a scene, a camera file, a config, an image. Readers that allocate from a header
  (PLY counts, ``.npy`` shapes, image dimensions, SOG counts) check those numbers against the file
  size and the documented maxima before allocating.
* **Paths inside a scene are confined to its folder** (:func:`confined`): a SOG ``meta.json`` or
  ``lod-meta.json`` may name files only below the scene's folder; absolute paths, ``..`` that
  climbs out, and symlinks that lead out are refused.
* **JSON**: bounded size; nesting too deep for the parser is an error, not a RecursionError.
* **YAML** (:mod:`harness.io.safe_yaml`): read as above; duplicate keys and alias bombs refused.
* **Images** (:func:`open_image`, :func:`image_size`): bytes read as above, the pixel count taken
  from the header and checked against the maximum render size before anything is decoded; so
  Pillow's own ``DecompressionBombWarning`` is silenced (process-wide, once this is imported).
* **What a command read is remembered** (:func:`recording_inputs`): while a CLI command runs,
  every file opened here is recorded by its identity ``(st_dev, st_ino)`` taken from the open
  descriptor, with the path the user gave. :mod:`harness.io.files` refuses to replace any of them,
  whatever other path names it (a symlinked folder, a hard link, a bind mount): inputs are never
  overwritten. State that a command reads in order to update it (a tracking baseline, the stage
  cache, the fetched copy of a named scene) is read with ``record=False``.

Every refusal is an :class:`~harness.core.errors.InputError` naming the file.

The caps can be raised for a machine that needs it with ``HARNESS_MAX_<KIND>_BYTES`` (e.g.
``HARNESS_MAX_SCENE_BYTES=17179869184``).
"""

from __future__ import annotations

import json
import os
import stat
import warnings
from contextlib import contextmanager
from pathlib import Path
from typing import BinaryIO

from harness.core.errors import InputError

KiB, MiB, GiB = 1 << 10, 1 << 20, 1 << 30
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"

# Pillow's DecompressionBombWarning (a RuntimeWarning): the readers check pixel counts themselves
warnings.filterwarnings("ignore", message=r"Image size \(\d+ pixels\) exceeds limit", category=RuntimeWarning)

#: default size caps (bytes) per kind of file
LIMITS = {
    "scene": 8 * GiB,       # .ply / .splat (a 6 M-splat SH-3 PLY is ~1.5 GB)
    "json": 64 * MiB,       # meta.json, lod-meta.json, cameras.json, transforms.json, run.json, baselines
    "config": 1 * MiB,      # YAML run configs
    "image": 512 * MiB,     # PNG / WebP / .npy images and SOG textures
    "camera_model": 256 * MiB,  # COLMAP cameras/images (.txt/.bin)
    "results": 1 * GiB,     # results.parquet / .csv
    "array": 8 * GiB,       # .npy arrays other than images
}

def limit(kind: str) -> int:
    env = os.environ.get(f"HARNESS_MAX_{kind.upper()}_BYTES")
    if env:
        try:
            return int(env)
        except ValueError:
            raise InputError(f"HARNESS_MAX_{kind.upper()}_BYTES", f"expected a number of bytes, got {env!r}") from None
    return LIMITS[kind]


# ----------------------------------------------------------------------------- inputs of a command
#: (st_dev, st_ino) -> the path as given, of every file read while a command runs (None: not recording)
_inputs: dict[tuple[int, int], str] | None = None


@contextmanager
def recording_inputs():
    """Record the identity of every file read in this block (the CLI wraps each command in one)."""
    global _inputs
    previous, _inputs = _inputs, {}
    try:
        yield
    finally:
        _inputs = previous


def _note(st: os.stat_result, path, record: bool) -> None:
    if record and _inputs is not None:
        _inputs.setdefault((st.st_dev, st.st_ino), str(path))


def input_named(st: os.stat_result) -> str | None:
    """The path (as given) of the input this command read that ``st`` identifies, or None."""
    return None if _inputs is None else _inputs.get((st.st_dev, st.st_ino))


def last_input() -> str | None:
    """The input this command read most recently (what a last-resort error message points at)."""
    return next(reversed(_inputs.values()), None) if _inputs else None


def kind_of(mode: int) -> str:
    """'a FIFO (named pipe)', 'a folder' ... of a non-regular ``st_mode``."""
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISCHR(mode):
        return "a character device"
    if stat.S_ISBLK(mode):
        return "a block device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def check_regular(path: str | Path, kind: str = "json", what: str = "file", record: bool = True) -> os.stat_result:
    """``stat`` (following symlinks) and refuse anything but a regular file within the size cap."""
    path = Path(path)
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise InputError(path, "no such file") from None
    except NotADirectoryError:
        raise InputError(path, "no such file (a parent is not a folder)") from None
    except OSError as err:
        raise InputError(path, f"cannot read: {err.strerror or err}") from None
    if not stat.S_ISREG(st.st_mode):
        raise InputError(path, f"is {kind_of(st.st_mode)}; expected a regular {what}")
    cap = limit(kind)
    if st.st_size > cap:
        raise InputError(path, f"is {st.st_size:,} bytes, more than the {cap:,}-byte limit for a {what} "
                               f"(HARNESS_MAX_{kind.upper()}_BYTES raises it)")
    _note(st, path, record)
    return st


def open_regular(path: str | Path, kind: str = "json", what: str = "file", record: bool = True) -> BinaryIO:
    """A binary file object of a checked regular file (see the module docstring)."""
    path = Path(path)
    check_regular(path, kind, what, record=False)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except OSError as err:
        raise InputError(path, f"cannot read: {err.strerror or err}") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):  # swapped between stat and open
            raise InputError(path, f"is {kind_of(st.st_mode)}; expected a regular {what}")
        if st.st_size > limit(kind):
            raise InputError(path, f"is {st.st_size:,} bytes, more than the {limit(kind):,}-byte limit")
        _note(st, path, record)
    except BaseException:
        os.close(fd)
        raise
    return os.fdopen(fd, "rb")


def read_bytes(path: str | Path, kind: str = "json", what: str = "file", record: bool = True) -> bytes:
    """All bytes of a checked regular file (at most its cap, read once)."""
    with open_regular(path, kind, what, record) as f:
        try:  # the size on disk (+1, for a file that grew), never the cap: read(n) allocates n bytes
            return f.read(min(os.fstat(f.fileno()).st_size, limit(kind)) + 1)
        except OSError as err:
            raise InputError(path, f"cannot read: {err.strerror or err}") from None


def read_text(path: str | Path, kind: str = "json", what: str = "file", record: bool = True) -> str:
    """UTF-8 text of a checked regular file; other encodings are an error."""
    data = read_bytes(path, kind, what, record)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as err:
        raise InputError(path, f"is not UTF-8 text (byte {err.start}: {data[err.start:err.start + 1]!r})") from None


def parse_json(text: str | bytes, source) -> object:
    """``json.loads`` with a depth limit and one-line errors."""
    if isinstance(text, bytes):
        try:
            text = text.decode("utf-8")
        except UnicodeDecodeError as err:
            raise InputError(source, f"not valid JSON (not UTF-8 at byte {err.start})") from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as err:
        raise InputError(source, f"not a readable JSON file (not valid JSON: {err})") from None
    except RecursionError:
        raise InputError(source, "JSON nested too deeply") from None


def read_json(path: str | Path, kind: str = "json", what: str = "JSON file", record: bool = True) -> object:
    return parse_json(read_text(path, kind, what, record), path)


def confined(root: str | Path, name: str, source) -> Path:
    """``root / name`` for a relative ``name`` that stays below ``root`` once symlinks are resolved;
    anything else (absolute, ``..`` climbing out, a symlink out) is an InputError naming ``source``."""
    if not isinstance(name, str) or not name or "\x00" in name:
        raise InputError(source, f"bad file name {name!r}")
    if name.startswith(("/", "\\")) or os.path.isabs(name) or (len(name) > 1 and name[1] == ":"):
        raise InputError(source, f"refers to {name!r}, an absolute path; only files inside the scene folder are read")
    root = Path(root).resolve()
    target = (root / name).resolve()
    if target != root and root not in target.parents:
        raise InputError(source, f"refers to {name!r}, outside the scene folder {root}; only files inside it are read")
    return target


# ----------------------------------------------------------------------------- .npy
def npy_header(f: BinaryIO, source) -> tuple[tuple[int, ...], object, bool]:
    """(shape, dtype, fortran_order) of an open ``.npy`` at its start; file position left at the data."""
    import numpy as np

    try:
        major, minor = np.lib.format.read_magic(f)
        if (major, minor) == (1, 0):
            shape, fortran, dtype = np.lib.format.read_array_header_1_0(f, max_header_size=10000)
        elif major in (2, 3):
            shape, fortran, dtype = np.lib.format.read_array_header_2_0(f, max_header_size=10000)
        else:
            raise ValueError(f"unknown .npy version {major}.{minor}")
    except (ValueError, OSError, EOFError, SyntaxError) as err:
        raise InputError(source, f"not a readable .npy array: {err}") from None
    if dtype.hasobject:
        raise InputError(source, ".npy holds Python objects (pickles are never loaded)")
    return tuple(int(s) for s in shape), dtype, fortran


def load_npy(path: str | Path, kind: str = "array", max_elements: int | None = None):
    """A ``.npy`` array whose header agrees with the file size exactly, checked before allocating."""
    import numpy as np

    path = Path(path)
    with open_regular(path, kind, ".npy file") as f:
        shape, dtype, fortran = npy_header(f, path)
        n = 1
        for s in shape:
            n *= s
        data_bytes = os.fstat(f.fileno()).st_size - f.tell()
        if max_elements is not None and n > max_elements:
            raise InputError(path, f".npy shape {shape} has {n:,} elements, more than the {max_elements:,} allowed")
        if n * dtype.itemsize != data_bytes:
            raise InputError(path, f".npy header declares shape {shape} of {dtype} ({n * dtype.itemsize:,} bytes) "
                                   f"but the file holds {data_bytes:,} bytes of data")
        arr = np.frombuffer(f.read(data_bytes), dtype=dtype) if n else np.zeros(0, dtype)
    arr = arr.reshape(shape[::-1]).transpose() if fortran else arr.reshape(shape)
    return np.array(arr)  # writable, owns its memory


# ----------------------------------------------------------------------------- images
def _pixels_bound(max_pixels: int | None) -> int:
    from harness.core.cameras import MAX_PIXELS

    return MAX_PIXELS if max_pixels is None else max_pixels


def image_size(path: str | Path, what: str = "image") -> tuple[int, int]:
    """(width, height) from an image file's header, read through :func:`open_regular`; nothing is
    decoded, and a header beyond the maximum render size is refused."""
    from PIL import Image, UnidentifiedImageError

    path = Path(path)
    with open_regular(path, "image", what) as f:
        try:
            with Image.open(f) as im:
                w, h = im.size
        except Image.DecompressionBombError as err:
            raise InputError(path, _bomb(err)) from None
        except (UnidentifiedImageError, OSError, SyntaxError, ValueError) as err:
            f.seek(0)
            raise InputError(path, f"not a readable image: {pillow_problem(err, f.read(24))}") from None
    _check_pixels(path, w, h, None)
    return w, h


def pillow_problem(err: BaseException, head: bytes = b"") -> str:
    """What Pillow could not open, in one line: an empty PNG (0 pixels wide or high) said so, never
    "cannot identify image file <_io.BytesIO object at 0x…>"; else Pillow's message, shortened."""
    if head[:8] == PNG_SIGNATURE and head[12:16] == b"IHDR" and len(head) >= 24:
        w, h = int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")
        if w == 0 or h == 0:
            return f"the PNG header says {w}x{h} pixels (an empty image)"
    text = " ".join(str(err).split())
    if text.startswith("cannot identify image file"):
        return "not an image format Pillow knows (or truncated, or empty)"
    return text[:160]


def _bomb(err) -> str:
    """Pillow refused a header before we could read its size: it claims even more than its own limit."""
    from harness.core.cameras import MAX_SIDE

    return f"image is larger than the maximum ({MAX_SIDE} per side): {' '.join(str(err).split())[:120]}"


def _check_pixels(path, w: int, h: int, max_pixels: int | None) -> None:
    from harness.core.cameras import MAX_SIDE

    bound = _pixels_bound(max_pixels)
    if w > MAX_SIDE or h > MAX_SIDE or w * h > bound:
        raise InputError(path, f"image is {w}x{h} pixels, larger than the maximum ({MAX_SIDE} per side)")


def open_image(path: str | Path, what: str = "image", mode: str | None = "RGB", record: bool = True):
    """A decoded PIL image of a checked regular file: size-capped bytes, the header's pixel count
    checked before decoding, truncated or corrupt data an InputError (not a half-decoded image)."""
    import io

    from PIL import Image, UnidentifiedImageError

    path = Path(path)
    data = read_bytes(path, "image", what, record)
    try:
        with Image.open(io.BytesIO(data)) as im:
            _check_pixels(path, *im.size, None)
            im.load()
            return im.convert(mode) if mode and im.mode != mode else im.copy()
    except Image.DecompressionBombError as err:
        raise InputError(path, _bomb(err)) from None
    except (UnidentifiedImageError, OSError, SyntaxError, ValueError) as err:
        raise InputError(path, f"not a readable image: {pillow_problem(err, data[:24])}") from None
