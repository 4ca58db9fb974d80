"""TOML files for scenes and sweeps: read, parse, write and check keys, with errors that name the key.

Read errors start with the file's path, key errors name the full dotted key and the allowed keys
(the values themselves are checked by `labrig.validate`), and values are written so that they read
back exactly.
"""

from __future__ import annotations

import json
import math
import os

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

from .files import existing_file
from .validate import InputError, typed

#: Largest parameter file read, bytes.
MAX_BYTES = 16 * 2**20

__all__ = ["read_toml", "parse_toml", "from_source", "toml_value", "toml_line", "check_keys", "top_level", "as_table",
           "tomllib"]


def parse_toml(text: str, source: str = "<string>") -> dict:
    """Parse TOML text; a ValueError starting with ``source`` if it is not valid TOML."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{source}: invalid TOML: {exc}") from None


def from_source(build, data: dict, source: str, *args):
    """``build(data, *args)``, with an `InputError`'s message prefixed by ``source`` (a path or "<string>")."""
    try:
        return build(data, *args)
    except InputError as exc:
        raise InputError(f"{source}: {exc}") from None


def read_toml(path: str | os.PathLike, what: str) -> dict:
    """Read and parse the TOML file ``path`` (``what`` names it in messages, e.g. "scene file").

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    InputError
        If it is not a regular file, is larger than `MAX_BYTES`, cannot be read or decoded (UTF-8)
        or is not valid TOML; the message starts with the path.
    """
    path = existing_file(path, what)
    if path.stat().st_size > MAX_BYTES:
        raise InputError(f"{path}: the {what} is {path.stat().st_size:,} bytes, more than the {MAX_BYTES:,} "
                         "a parameter file may have")
    try:
        text = path.read_bytes().decode("utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: cannot read the {what}: {exc}") from None
    return parse_toml(text, str(path))


def toml_value(v) -> str:
    """One TOML value: bool, int, float (repr, exact), string or flat list."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return repr(v) if math.isfinite(v) else ("nan" if math.isnan(v) else ("inf" if v > 0 else "-inf"))
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False).replace("\x7f", "\\u007f")  # TOML also escapes DEL
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    raise ValueError(f"cannot write {v!r} ({type(v).__name__}) to TOML")


def toml_line(key: str, value, comment: str | None, default=None) -> str:
    """``key = value  # comment``; an unset (None) value is written as a comment, or as ``key = false``
    when the key's ``default`` is set (a missing key would read back as that default)."""
    if value is None:
        text = f"# {key} (unset)" if default is None else f"{key} = false"
    else:
        text = f"{key} = {toml_value(value)}"
    return f"{text:<32}  # {comment}" if comment else text


def check_keys(where: str, keys, allowed) -> None:
    """ValueError naming the first key of ``keys`` not in ``allowed`` (``where``: the table, "" at top level)."""
    extra = [k for k in keys if k not in allowed]
    if extra:
        full = f"{where}.{extra[0]}" if where else extra[0]
        raise InputError(f"unknown key {full!r} (allowed{' in [' + where + ']' if where else ''}: "
                         f"{', '.join(allowed)})")


def top_level(data, top: dict, tables) -> dict:
    """The top-level values of a parsed parameter file, after checking its keys.

    Parameters
    ----------
    data : dict
        The parsed file.
    top : dict
        ``{key: (kind, comment)}``: its top-level values, of the kinds `labrig.validate.typed` checks.
    tables : sequence of str
        The tables (and arrays of tables) it may also hold.

    Returns
    -------
    dict
        The values of ``top`` that ``data`` holds, typed.

    Raises
    ------
    labrig.validate.InputError
        If ``data`` is not a table, holds an unknown key, or a value of ``top`` of the wrong kind.
    """
    if not isinstance(data, dict):
        raise InputError(f"a scene must be a table, got {type(data).__name__}")
    check_keys("", data, [*top, *tables])
    return {key: typed(key, data[key], kind) for key, (kind, _) in top.items() if key in data}


def as_table(name: str, value) -> dict:
    """``value``, the table ``name`` of a parameter file; an `InputError` if it is not a table."""
    if not isinstance(value, dict):
        raise InputError(f"{name} must be a table ([{name}]), got {value!r}")
    return value
