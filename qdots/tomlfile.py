"""TOML files for scenes and sweeps: read, parse, write and check, with errors that name the key.

Shared by `qdots.scenefile`, `planarize.scenefile` and `qdots.sweeps.files`:
read errors start with the file's path, checking errors name the full dotted
key and the allowed values, and values are written so they read back exactly.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

__all__ = ["read_toml", "parse_toml", "from_source", "toml_value", "toml_line", "typed", "check_keys", "tomllib"]


def parse_toml(text: str, source: str = "<string>") -> dict:
    """Parse TOML text; a ValueError starting with ``source`` if it is not valid TOML."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{source}: invalid TOML: {exc}") from None


def from_source(build, data: dict, source: str, *args):
    """``build(data, *args)``, with a ValueError's message prefixed by ``source`` (a path or "<string>")."""
    try:
        return build(data, *args)
    except ValueError as exc:
        raise ValueError(f"{source}: {exc}") from None


def read_toml(path: str | os.PathLike, what: str) -> dict:
    """Read and parse the TOML file ``path`` (``what`` names it in messages, e.g. "scene file").

    Raises
    ------
    FileNotFoundError
        If ``path`` is not a file.
    ValueError
        If it cannot be read or decoded (UTF-8) or is not valid TOML; the message starts with the path.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{what} {str(path)!r} does not exist")
    try:
        text = path.read_bytes().decode("utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: cannot read the {what}: {exc}") from None
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


def toml_line(key: str, value, comment: str | None) -> str:
    """``key = value  # comment``; an unset (None) value is written as a comment."""
    text = f"# {key} (unset)" if value is None else f"{key} = {toml_value(value)}"
    return f"{text:<32}  # {comment}" if comment else text


def typed(key: str, value, kind: str):
    """``value`` checked against ``kind``; ValueError naming the full ``key`` otherwise.

    Kinds: "float", "int", "str", "bool", "pair" (``[number, integer]``); a
    trailing "?" marks a key that may be unset.
    """
    plain = kind.rstrip("?")
    if plain == "float" and isinstance(value, (int, float)) and not isinstance(value, bool):
        return float(value)
    if plain == "int" and isinstance(value, int) and not isinstance(value, bool):
        return value
    if plain in ("str", "bool") and isinstance(value, {"str": str, "bool": bool}[plain]):
        return value
    if plain == "pair" and isinstance(value, list) and len(value) == 2 \
            and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in value) \
            and isinstance(value[1], int):
        return (float(value[0]), value[1])
    want = {"float": "a number", "int": "an integer", "str": "a string", "bool": "true or false",
            "pair": "a list [number, integer]"}[plain]
    raise ValueError(f"{key} must be {want}, got {value!r}")


def check_keys(where: str, keys, allowed) -> None:
    """ValueError naming the first key of ``keys`` not in ``allowed`` (``where``: the table, "" at top level)."""
    extra = [k for k in keys if k not in allowed]
    if extra:
        full = f"{where}.{extra[0]}" if where else extra[0]
        raise ValueError(f"unknown key {full!r} (allowed{' in [' + where + ']' if where else ''}: "
                         f"{', '.join(allowed)})")
