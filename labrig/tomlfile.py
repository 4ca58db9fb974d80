"""TOML files for scenes and sweeps: read, parse, write and check keys, with errors that name the key.

Read errors start with the file's path, key errors name the full dotted key and the allowed keys
(the values themselves are checked by `labrig.validate`), and values are written so that they read
back exactly.

Every parameter file goes through `parse_toml`, which refuses hostile text in one line before the
parser builds it: more than `MAX_BYTES`, tables and arrays nested deeper than `MAX_DEPTH` (the parser
recurses once per level of brackets) or more than `MAX_CONTAINERS` of them (a megabyte of table
headers would build hundreds of megabytes of tables), and, once parsed, integers outside TOML's 64
bits. A UTF-8 byte order mark at the start is skipped.
"""

from __future__ import annotations

import json
import math
import os
import re

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

from .files import existing_file
from .validate import InputError, typed

#: Largest parameter file read, bytes (a scene file is about 1 kB, a sweep of a thousand explicit points
#: about 100 kB; parsing a megabyte of TOML takes about a second).
MAX_BYTES = 2**20
#: Deepest nesting of tables and arrays in a parameter file, the top-level table counting as one
#: (a scene file reaches 4, a sweep file 5).
MAX_DEPTH = 64
#: Most tables and arrays a parameter file may open, counting one per part of a table header or a dotted
#: key (at most about 20 MB once parsed).
MAX_CONTAINERS = 20_000
#: The integers TOML holds (64-bit, signed).
INT_RANGE = (-2**63, 2**63 - 1)

__all__ = ["read_toml", "parse_toml", "from_source", "toml_value", "toml_line", "check_keys", "top_level", "as_table",
           "tomllib", "MAX_BYTES", "MAX_DEPTH", "MAX_CONTAINERS", "INT_RANGE"]


# where the structure scan stops: the openings of strings and comments, brackets, and what joins or ends a key
_MARK = re.compile(r'"""|\'\'\'|["\'#\[\]{}.=,\n]')
# the rest of a string after its opening quotes, to its closing ones (or where it is left unterminated);
# none of them can fail or backtrack
_STRING_REST = {
    '"""': re.compile(r'[^"\\]*(?:(?:\\.|"(?!""))[^"\\]*)*(?:""""{0,2})?', re.DOTALL),
    "'''": re.compile(r"[^']*(?:'(?!'')[^']*)*(?:''''{0,2})?"),
    '"': re.compile(r'[^"\\\n]*(?:\\.[^"\\\n]*)*"?'),
    "'": re.compile(r"[^'\n]*'?"),
}


def _structure_problem(text: str) -> str | None:
    """What makes ``text`` too deep or too big to parse (None if nothing does), from its brackets and dotted
    keys alone (strings and comments skipped): more than `MAX_DEPTH` levels of brackets plus dotted key
    parts in one statement, or more than `MAX_CONTAINERS` of them in all."""
    brackets: list[str] = []  # "[" array, "{" inline table, "h" a bracket of a table header
    in_key = True  # reading a key: at the start of a top-level line, after "{" or "," in an inline table
    dots = opened = pos = 0
    while (mark := _MARK.search(text, pos)) is not None:
        char, pos = mark.group(), mark.end()
        if char in _STRING_REST:
            rest = _STRING_REST[char].match(text, pos)
            pos = rest.end() if rest is not None else len(text)  # the patterns match any text (maybe empty)
        elif char == "#":
            end = text.find("\n", pos)
            pos = len(text) if end < 0 else end
        elif char == "\n":
            if not brackets:
                in_key, dots = True, 0
        elif char == "=":
            in_key, dots = False, 0
        elif char == ",":
            if brackets and brackets[-1] == "{":
                in_key, dots = True, 0
        elif char == ".":
            if in_key:
                dots, opened = dots + 1, opened + 1
        elif char in "[{":
            header = char == "[" and in_key and (not brackets or brackets[-1] == "h")
            brackets.append("h" if header else char)
            if not header:
                in_key, dots = char == "{", 0
            opened += 1
        else:  # "]" or "}": a value or a header ends
            if brackets:
                brackets.pop()
            in_key = False
        if len(brackets) + dots > MAX_DEPTH:
            return f"tables and arrays nested more than {MAX_DEPTH} deep (at line {text.count(chr(10), 0, pos) + 1})"
        if opened > MAX_CONTAINERS:
            return f"more than {MAX_CONTAINERS:,} tables and arrays (at line {text.count(chr(10), 0, pos) + 1})"
    return None


def _value_problem(data: dict) -> str | None:
    """What in parsed TOML is out of bounds (None if nothing is): nesting deeper than `MAX_DEPTH` (the
    top-level table is 1) or an integer outside `INT_RANGE`."""
    pending: list[tuple[dict | list, int, str]] = [(data, 1, "")]
    while pending:
        node, depth, where = pending.pop()
        if depth > MAX_DEPTH:
            return f"tables and arrays nested more than {MAX_DEPTH} deep (at {where[:60]}{'...' * (len(where) > 60)})"
        items = node.items() if isinstance(node, dict) else ((f"[{i}]", v) for i, v in enumerate(node))
        for key, value in items:
            name = f"{where}{key}" if isinstance(node, list) else f"{where}.{key}" if where else str(key)
            if isinstance(value, (dict, list)):
                pending.append((value, depth + 1, name))
            elif isinstance(value, int) and not isinstance(value, bool) and \
                    not INT_RANGE[0] <= value <= INT_RANGE[1]:
                digits = len(str(abs(value)))
                shown = str(value) if digits <= 30 else f"an integer of {digits} digits"
                return f"{name} = {shown} is outside the 64-bit integers TOML holds"
    return None


def parse_toml(text: str, source: str = "<string>") -> dict:
    """Parse TOML text (a leading byte order mark skipped).

    Raises
    ------
    labrig.validate.InputError
        Starting with ``source``, if the text is longer than `MAX_BYTES` characters, not valid TOML,
        nests tables and arrays deeper than `MAX_DEPTH`, opens more than `MAX_CONTAINERS` of them or
        holds an integer outside `INT_RANGE`.
    """
    if len(text) > MAX_BYTES:
        raise InputError(f"{source}: the TOML text is {len(text):,} characters, more than the {MAX_BYTES:,} "
                         "a parameter file may have")
    text = text.removeprefix("\ufeff")
    problem = _structure_problem(text)
    if problem is None:
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise InputError(f"{source}: invalid TOML: {exc}") from None
        except ValueError as exc:  # an integer of thousands of digits: Python's limit on int("...")
            raise InputError(f"{source}: invalid TOML: {str(exc).split(';')[0]}") from None
        except RecursionError:  # the scan bounds the parser's recursion; this is the last resort
            raise InputError(f"{source}: invalid TOML: tables and arrays nested too deep") from None
        problem = _value_problem(data)
    if problem is not None:
        raise InputError(f"{source}: invalid TOML: {problem}")
    return data


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
