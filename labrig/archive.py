"""Archives of arrays and metadata: one ``.npz`` file (NumPy's zip of ``.npy`` members) with a JSON object.

`write_archive` writes atomically (`labrig.files.atomic_path`). `read_archive` reads only what the
caller says the format holds, and never unpickles: before it loads an array it checks each member's
name and size against the caller's limits (`MAX_ARCHIVE_BYTES` and the memory available in all), and
reads its ``.npy`` header to check that it holds numbers and that its shape accounts for exactly the
bytes the member holds. A forged header (a shape of 10**12 rows in 80 bytes) or a compressed member
that would inflate to gigabytes is refused before anything is allocated.
"""

from __future__ import annotations

import json
import math
import os
import zipfile
import zlib
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from .files import atomic_path, existing_file
from .jsonfile import parse_json
from .validate import InputError, available_memory, within_memory

__all__ = ["write_archive", "read_archive", "MAX_ARCHIVE_BYTES", "MAX_METADATA_CHARS",
           "MAX_MEMBERS"]

#: Largest archive `read_archive` loads, bytes uncompressed.
MAX_ARCHIVE_BYTES = 16 * 2**30
#: Longest metadata (its JSON text), characters.
MAX_METADATA_CHARS = 2**20
#: Most members (arrays) of an archive.
MAX_MEMBERS = 1000
#: Bytes per character of the metadata member (NumPy stores text as UTF-32).
_CHAR_BYTES = 4
#: The dtype kinds of the arrays read: booleans, integers, floats, complex numbers.
_NUMBERS = "biufc"
#: Most bytes of a ``.npy`` header of version 1.0 or 2.0 that NumPy reads (magic, length, 64 kB of text).
_HEADER_BYTES = 2**16 + 16


def write_archive(path: str | os.PathLike, metadata: dict, arrays: dict) -> Path:
    """Write ``arrays`` and ``metadata`` (as one JSON string) to an ``.npz`` archive at ``path``, atomically."""
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as stream:  # a file object stops np.savez appending ".npz"
            np.savez(stream, metadata=np.array(json.dumps(metadata)), **arrays)
    return Path(path)


def read_archive(path: str | os.PathLike, kind: str, version: int, names: Sequence[str], what: str | None = None,
                 *, max_bytes: Mapping[str, int]) -> tuple[dict, dict]:
    """The metadata and arrays of an archive `write_archive` wrote, checked to be of ``kind`` and ``version``.

    Parameters
    ----------
    path : path
        The ``.npz`` file.
    kind : str
        Its ``metadata["format"]`` (e.g. ``"qdots-state"``), also how messages name it.
    version : int
        The format version this reader reads.
    names : sequence of str
        Arrays it must hold.
    what : str, optional
        How messages name the file (default ``kind``), e.g. ``"qdots state"``.
    max_bytes : mapping of str to int
        The largest size of each array the format holds, bytes of values (its ``.npy`` header not counted),
        by array name; a name ending in ``*`` stands for every name it begins (``"history_*"``). An array
        no name covers is refused.

    Returns
    -------
    metadata : dict
        The JSON object of metadata.
    arrays : dict of ndarray
        Every array, by name.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    labrig.validate.InputError
        If it is not a regular file, not a readable ``.npz`` archive (truncated, corrupted, a ``.npy``
        array under another name, a member that is not a ``.npy`` array of numbers, a ``.npy`` header whose
        shape does not match the bytes it holds), holds an array ``max_bytes`` does not cover or allow,
        more than `MAX_ARCHIVE_BYTES` in all or more than the memory available, has no JSON object of
        metadata (of at most `MAX_METADATA_CHARS`), is of another format or version, or lacks an array;
        the message starts with the path.
    """
    what = what or kind
    if not Path(path).exists():
        raise FileNotFoundError(f"no such {what} file: {path}")
    path = existing_file(path, f"{what} file")
    # what a damaged archive raises (InputError among them); zlib.error and the rest for a damaged compressed
    # member, a compression method or an encryption zipfile does not read
    readable = (zipfile.BadZipFile, zlib.error, EOFError, OSError, ValueError, KeyError, TypeError,
                NotImplementedError, RuntimeError)
    try:
        archive = zipfile.ZipFile(path)
    except readable as exc:
        raise _unreadable(path, what, exc) from None
    with archive:
        try:
            members = _members(archive)
            if "metadata" not in members:
                raise InputError("no metadata in it")
            metadata = _metadata(archive, members.pop("metadata"))
        except readable as exc:
            raise _unreadable(path, what, exc) from None
        if metadata.get("format") != kind:
            raise InputError(f"{path} is not a {what} file (format {metadata.get('format')!r})")
        if metadata.get("version") != version:
            raise InputError(f"{path} has {what} format version {metadata.get('version')!r}; this reads version "
                             f"{version}")
        missing = [name for name in names if name not in members]
        if missing:
            raise InputError(f"{path} is not a readable {what} file: no {', '.join(missing)} in it")
        try:
            limits = _check_sizes(members, max_bytes)
            for name, info in members.items():
                _check_header(archive, info, _NUMBERS, limits[name])
            arrays = {name: _load(archive, info) for name, info in members.items()}
        except readable as exc:
            raise _unreadable(path, what, exc) from None
    return metadata, arrays


def _unreadable(path: Path, what: str, exc: Exception) -> InputError:
    if isinstance(exc, InputError):
        return InputError(f"{path} is not a readable {what} file: {exc}")
    return InputError(f"{path} is not a readable {what} file ({type(exc).__name__}: {exc})")


def _members(archive: zipfile.ZipFile) -> dict[str, zipfile.ZipInfo]:
    """The members of ``archive`` by array name (``positions.npy`` is ``positions``)."""
    infos = archive.infolist()
    if len(infos) > MAX_MEMBERS:
        raise InputError(f"it has {len(infos):,} members, more than the {MAX_MEMBERS:,} read")
    members: dict[str, zipfile.ZipInfo] = {}
    for info in infos:
        name = info.filename.removesuffix(".npy")
        if name == info.filename or info.is_dir():
            raise InputError(f"its member {info.filename!r} is not a .npy array")
        if name in members:
            raise InputError(f"it holds {info.filename!r} twice")
        members[name] = info
    return members


def _limit(name: str, max_bytes: Mapping[str, int]) -> int | None:
    if name in max_bytes:
        return max_bytes[name]
    return next((limit for key, limit in max_bytes.items() if key.endswith("*") and name.startswith(key[:-1])),
                None)


def _check_sizes(members: dict, max_bytes: Mapping[str, int]) -> dict[str, int]:
    """The limit of each member, bytes of values: every member covered by ``max_bytes`` and within it (with
    its header), all of them within `MAX_ARCHIVE_BYTES` and the memory available (their sizes as the archive
    declares them: no member is read beyond its size, whatever its compressed data inflates to)."""
    limits: dict[str, int] = {}
    for name, info in members.items():
        limit = _limit(name, max_bytes)
        if limit is None:
            raise InputError(f"it holds an array {name!r}, which this format has not")
        limits[name] = limit
        if info.file_size > limit + _HEADER_BYTES:
            raise InputError(f"its array {name!r} is {info.file_size:,} bytes, more than the {limit:,} this format "
                             "holds")
    total = sum(info.file_size for info in members.values())
    if total > MAX_ARCHIVE_BYTES:
        raise InputError(f"it holds {total:,} bytes, more than the {MAX_ARCHIVE_BYTES:,} read")
    within_memory("its arrays", total, available_memory())
    return limits


def _check_header(archive: zipfile.ZipFile, info: zipfile.ZipInfo, kinds: str, limit: int) -> tuple[np.dtype, tuple]:
    """The dtype and shape in the ``.npy`` header of ``info``, checked: a dtype of one of ``kinds`` and a shape
    whose values fill exactly the rest of the member, at most ``limit`` bytes. Reads the header only."""
    with archive.open(info) as stream:
        npy_version = np.lib.format.read_magic(stream)
        if npy_version not in ((1, 0), (2, 0)):
            raise InputError(f"{info.filename} is a .npy file of version {npy_version}, not 1.0 or 2.0")
        read_header = np.lib.format.read_array_header_1_0 if npy_version == (1, 0) else \
            np.lib.format.read_array_header_2_0
        try:
            shape, _, dtype = read_header(stream)
        except Exception as exc:  # NumPy parses the header as a Python literal: damage raises anything
            why = (str(exc).splitlines() or [""])[0][:200]
            raise InputError(f"{info.filename} has a damaged .npy header ({type(exc).__name__}: {why})") from None
        data_bytes = info.file_size - stream.tell()
    if dtype.hasobject or dtype.kind not in kinds or dtype.itemsize == 0:
        raise InputError(f"{info.filename} holds {dtype} values, not " + ("text" if kinds == "U" else "numbers"))
    declared = math.prod(shape) * dtype.itemsize
    if declared != data_bytes:
        raise InputError(f"{info.filename} declares {' x '.join(map(str, shape)) or 'one'} {dtype} values "
                         f"({declared:,} bytes) but holds {data_bytes:,} bytes")
    if declared > limit:
        raise InputError(f"{info.filename} holds {declared:,} bytes of values, more than the {limit:,} this format "
                         "holds")
    return dtype, shape


def _load(archive: zipfile.ZipFile, info: zipfile.ZipInfo) -> np.ndarray:
    """The array of a member whose header `_check_header` passed (its checksum is checked as it is read)."""
    with archive.open(info) as stream:
        return np.lib.format.read_array(stream, allow_pickle=False)


def _metadata(archive: zipfile.ZipFile, info: zipfile.ZipInfo) -> dict:
    """The JSON object of the metadata member: one string of at most `MAX_METADATA_CHARS`."""
    limit = MAX_METADATA_CHARS * _CHAR_BYTES
    if info.file_size > limit + _HEADER_BYTES:
        raise InputError(f"its metadata is {info.file_size:,} bytes, more than the {limit:,} read")
    _, shape = _check_header(archive, info, "U", limit)
    if shape != ():
        raise InputError(f"its metadata is an array of shape {shape}, not one string")
    metadata = parse_json(str(_load(archive, info)[()]), "metadata", MAX_METADATA_CHARS)
    if not isinstance(metadata, dict):
        raise InputError(f"its metadata is {type(metadata).__name__}, not an object")
    return metadata
