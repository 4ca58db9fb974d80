"""Archives of arrays and metadata: one ``.npz`` file (NumPy's zip of ``.npy`` members) with a JSON object.

`write_archive` writes atomically (`labrig.files.atomic_path`); `read_archive` checks the archive's
kind, version, members and sizes before it loads anything, and never unpickles.
"""

from __future__ import annotations

import json
import os
import zipfile
from pathlib import Path
from typing import Sequence

import numpy as np

from .files import atomic_path, existing_file
from .validate import InputError

__all__ = ["write_archive", "read_archive", "MAX_ARCHIVE_BYTES"]

#: Largest archive `read_archive` loads, bytes uncompressed.
MAX_ARCHIVE_BYTES = 16 * 2**30


def write_archive(path: str | os.PathLike, metadata: dict, arrays: dict) -> Path:
    """Write ``arrays`` and ``metadata`` (as one JSON string) to an ``.npz`` archive at ``path``, atomically."""
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as stream:  # a file object stops np.savez appending ".npz"
            np.savez(stream, metadata=np.array(json.dumps(metadata)), **arrays)
    return Path(path)


def read_archive(path: str | os.PathLike, kind: str, version: int, names: Sequence[str],
                 what: str | None = None) -> tuple[dict, dict]:
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
        Arrays it must hold (others are read too).
    what : str, optional
        How messages name the file (default ``kind``), e.g. ``"qdots state"``.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    labrig.validate.InputError
        If it is not a regular file, not a readable ``.npz`` archive (truncated, corrupted, a ``.npy``
        array under another name), larger than `MAX_ARCHIVE_BYTES`, has no JSON object of metadata,
        is of another format or version, or lacks an array; the message starts with the path.
    """
    what = what or kind
    if not Path(path).exists():
        raise FileNotFoundError(f"no such {what} file: {path}")
    path = existing_file(path, f"{what} file")
    try:
        with zipfile.ZipFile(path) as archive:
            size = sum(info.file_size for info in archive.infolist())
            if size > MAX_ARCHIVE_BYTES:
                raise InputError(f"it holds {size:,} bytes, more than the {MAX_ARCHIVE_BYTES:,} read")
            damaged = archive.testzip()  # every member against its checksum (numpy's reader does not check)
            if damaged is not None:
                raise InputError(f"{damaged} is damaged (its checksum does not match)")
        with np.load(path, allow_pickle=False) as data:
            if "metadata" not in data.files:
                raise InputError("no metadata in it")
            arrays = {name: data[name] for name in data.files}
        metadata = json.loads(str(arrays.pop("metadata")))
    except InputError as exc:
        raise InputError(f"{path} is not a readable {what} file: {exc}") from None
    except (zipfile.BadZipFile, EOFError, OSError, ValueError, KeyError, TypeError) as exc:
        raise InputError(f"{path} is not a readable {what} file ({type(exc).__name__}: {exc})") from None
    if not isinstance(metadata, dict):
        raise InputError(f"{path} is not a {what} file: its metadata is {type(metadata).__name__}, not an object")
    if metadata.get("format") != kind:
        raise InputError(f"{path} is not a {what} file (format {metadata.get('format')!r})")
    if metadata.get("version") != version:
        raise InputError(f"{path} has {what} format version {metadata.get('version')!r}; this reads version {version}")
    missing = [name for name in names if name not in arrays]
    if missing:
        raise InputError(f"{path} is not a readable {what} file: no {', '.join(missing)} in it")
    return metadata, arrays
