"""What a ``.npz`` file declares, read from its zip directory and array headers alone.

A weights file is shared like a scenario, so nothing of it is trusted before it is checked:
a header declaring a shape of 2^45, one extra zero-filled entry that inflates to gigabytes,
a 400 MB file. :func:`npz_members` reads only the zip's central directory and the few
hundred bytes of each member's ``.npy`` header (parsed by numpy's own header reader, a
literal, never code), and refuses a file larger than the cap, a member that is not a plain
``.npy`` array, an object dtype, or a declared array larger than its member, before any
array is read. The caller then checks names, dtypes and shapes, and only then loads.
"""

from __future__ import annotations

import math
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.lib import format as npy_format

MAX_HEADER_BYTES = 10_000
"""Largest ``.npy`` header read (numpy's own default limit)."""


class NpzError(ValueError):
    """A ``.npz`` that is not a small set of plain arrays (the message says which part)."""


@dataclass(frozen=True)
class Declared:
    """One member's array as its header declares it (nothing of the data read)."""

    dtype: np.dtype
    shape: tuple[int, ...]

    @property
    def nbytes(self) -> int:
        """Bytes of the data (exact integer arithmetic, no overflow)."""
        return math.prod(self.shape) * self.dtype.itemsize


def _header(archive: zipfile.ZipFile, info: zipfile.ZipInfo) -> Declared:
    with archive.open(info) as handle:
        try:
            version = npy_format.read_magic(handle)
            if version == (1, 0):
                shape, _, dtype = npy_format.read_array_header_1_0(
                    handle, max_header_size=MAX_HEADER_BYTES
                )
            elif version in ((2, 0), (3, 0)):
                shape, _, dtype = npy_format.read_array_header_2_0(
                    handle, max_header_size=MAX_HEADER_BYTES
                )
            else:
                raise NpzError(f"{info.filename}: .npy version {version} is not supported")
        except NpzError:
            raise
        except (ValueError, EOFError, OSError, SyntaxError, TypeError) as exc:
            reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise NpzError(f"{info.filename}: not a .npy array ({reason:.120})") from None
    if dtype.hasobject:
        raise NpzError(f"{info.filename}: holds Python objects (dtype {dtype}); allowed: numbers")
    return Declared(dtype, tuple(int(n) for n in shape))


def npz_members(path: Path, max_bytes: int) -> dict[str, Declared]:
    """Name (without ``.npy``) -> declared dtype and shape of every array in ``path``.

    Raises:
        NpzError: the file or its arrays exceed ``max_bytes``, a member is not a ``.npy``
            array, a name repeats, or a header declares more data than its member holds.
    """
    size = path.stat().st_size
    if size > max_bytes:
        raise NpzError(f"the file is {size:,} bytes; at most {max_bytes:,} are read")
    try:
        with zipfile.ZipFile(path) as archive:
            infos = archive.infolist()
            total = sum(info.file_size for info in infos)
            if total > max_bytes:
                raise NpzError(
                    f"its arrays unpack to {total:,} bytes; at most {max_bytes:,} are read"
                )
            members: dict[str, Declared] = {}
            for info in infos:
                name = info.filename.removesuffix(".npy")
                if not info.filename.endswith(".npy") or name in members:
                    raise NpzError(f"{info.filename!r} is not one plain .npy array")
                declared = _header(archive, info)
                if declared.nbytes > info.file_size:
                    raise NpzError(
                        f"{name} declares shape {declared.shape} of {declared.dtype} "
                        f"({declared.nbytes:,} bytes) in a {info.file_size:,}-byte entry"
                    )
                members[name] = declared
    except (zipfile.BadZipFile, zipfile.LargeZipFile, EOFError, OSError) as exc:
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise NpzError(f"not a readable .npz ({reason:.120})") from None
    return members
