"""JSON the packages read back (sweep records, ``sweep.json``, archive metadata), bounded before it is parsed.

Python's JSON parser recurses once per level of nesting and builds everything it reads: text nested
thousands deep raises RecursionError, a few megabytes of ``[[],[],...]`` become hundreds of megabytes
of lists, and an integer of thousands of digits fails Python's conversion limit. `parse_json` first
scans the text (strings skipped) and refuses it in one line, an `InputError` starting with where it
came from, if it is longer than its limit, nests deeper than `MAX_DEPTH`, opens more than
`MAX_CONTAINERS` arrays and objects or holds an integer of more than `MAX_INT_DIGITS` digits. What the
value must hold is the caller's to check.
"""

from __future__ import annotations

import json
import os
import re

from .files import existing_file
from .validate import InputError

__all__ = ["parse_json", "read_json", "MAX_BYTES", "MAX_DEPTH", "MAX_CONTAINERS", "MAX_INT_DIGITS"]

#: Largest JSON text read, characters (a sweep of the most runs, `labrig.sweeps.spec.MAX_RUNS`, writes a
#: ``sweep.json`` of about 2 MB).
MAX_BYTES = 16 * 2**20
#: Deepest nesting of arrays and objects: above the `labrig.tomlfile.MAX_DEPTH` of the parameters that
#: records and archive metadata hold, plus the few levels around them.
MAX_DEPTH = 100
#: Most arrays and objects in one text (a few megabytes of Python objects at most).
MAX_CONTAINERS = 100_000
#: Most digits of an integer (a 128-bit random generator state has 39).
MAX_INT_DIGITS = 100

# a string (to its closing quote, or to the end when unterminated: it cannot fail or backtrack) or a bracket
_TOKEN = re.compile(r'"[^"\\]*(?:\\.[^"\\]*)*"?|[\[\]{}]', re.DOTALL)


def _structure_problem(text: str) -> str | None:
    """What nests too deep or opens too many arrays and objects in ``text`` (None if nothing does)."""
    depth = opened = 0
    for token in _TOKEN.finditer(text):
        char = text[token.start()]
        if char in "[{":
            depth, opened = depth + 1, opened + 1
            if depth > MAX_DEPTH:
                return f"arrays and objects nested more than {MAX_DEPTH} deep (at character {token.start():,})"
            if opened > MAX_CONTAINERS:
                return f"more than {MAX_CONTAINERS:,} arrays and objects"
        elif char in "]}":
            depth -= 1  # unbalanced brackets are the parser's to report
    return None


def _integer(digits: str) -> int:
    if len(digits.lstrip("-")) > MAX_INT_DIGITS:
        raise ValueError(f"an integer of {len(digits.lstrip('-')):,} digits, more than the {MAX_INT_DIGITS} read")
    return int(digits)


def parse_json(text: str, source: str = "<string>", max_chars: int = MAX_BYTES):
    """The value of the JSON ``text`` (a leading byte order mark skipped).

    Parameters
    ----------
    text : str
        The JSON text.
    source : str
        Where it came from (a path, ``"<string>"``): the start of every message.
    max_chars : int
        Longest text parsed, characters.

    Raises
    ------
    labrig.validate.InputError
        If the text is longer than ``max_chars``, nests deeper than `MAX_DEPTH`, opens more than
        `MAX_CONTAINERS` arrays and objects, holds an integer of more than `MAX_INT_DIGITS` digits or is
        not valid JSON.
    """
    if len(text) > max_chars:
        raise InputError(f"{source}: the JSON text is {len(text):,} characters, more than the {max_chars:,} read")
    text = text.removeprefix("\ufeff")
    problem = _structure_problem(text)
    if problem is not None:
        raise InputError(f"{source}: invalid JSON: {problem}")
    try:
        return json.loads(text, parse_int=_integer)
    except ValueError as exc:  # JSONDecodeError, or an integer too long
        raise InputError(f"{source}: invalid JSON: {exc}") from None
    except RecursionError:  # the scan bounds the parser's recursion; this is the last resort
        raise InputError(f"{source}: invalid JSON: arrays and objects nested too deep") from None


def read_json(path: str | os.PathLike, what: str, max_bytes: int = MAX_BYTES):
    """The value of the JSON file ``path`` (``what`` names it in messages, e.g. "sweep record").

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    labrig.validate.InputError
        If it is not a regular file, is larger than ``max_bytes``, cannot be read or decoded (UTF-8) or
        is refused by `parse_json`; the message starts with the path.
    """
    path = existing_file(path, what)
    size = path.stat().st_size
    if size > max_bytes:
        raise InputError(f"{path}: the {what} is {size:,} bytes, more than the {max_bytes:,} read")
    try:
        text = path.read_bytes().decode("utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: cannot read the {what}: {exc}") from None
    return parse_json(text, str(path), max_bytes)
