"""Numeric text tables (height maps as text) read in bounded memory.

`read_table` reads a table of numbers (whitespace, comma or semicolon separated; ``# key: value``
header lines; an optional first line of column names) piece by piece, never the whole file nor a
whole line at once: each number is stored as an 8-byte float as soon as it is read, and reading
stops with an `InputError` as soon as the table holds more numbers than the caller allows, or a row
has a different number of values than the first. Memory: 8 bytes per number kept, plus one piece
(`PIECE_CHARS`). The caller bounds the file's size first (`planarize.io.limits`).
"""

from __future__ import annotations

from array import array
from pathlib import Path

import numpy as np

from labrig.validate import InputError

#: Characters read at a time (a line longer than this is read in several pieces).
PIECE_CHARS = 1 << 16
#: Longest text of one number (``-1.2345678901234567e-100`` has 24 characters): a longer field is not a number.
MAX_FIELD_CHARS = 256


def read_table(path: Path, max_values: int, keys=(), limit_note: str = "") -> tuple[dict, np.ndarray]:
    """The header entries ``keys`` (lower case) and the numbers of a text table, shape (rows, columns).

    Parameters
    ----------
    path : Path
        A UTF-8 text file (a byte-order mark is allowed).
    max_values : int
        Most numbers the table may hold; more is an `InputError` raised as soon as they are read.
    keys : iterable of str
        Header entries to keep (``# Width: 4.0 µm`` is the entry ``"width"``); others are skipped.
    limit_note : str
        Why ``max_values`` is the limit, appended to its message.
    """
    reader = _TableReader(max_values, frozenset(keys), limit_note)
    try:
        with open(path, encoding="utf-8-sig", newline=None) as stream:
            while piece := stream.readline(PIECE_CHARS):
                reader.read(piece)
    except UnicodeDecodeError as exc:
        raise InputError(f"cannot read the file as UTF-8 text: {exc}") from None
    except OSError as exc:
        raise InputError(f"cannot read the file: {exc.strerror or exc}") from None
    return reader.header, reader.table()


class _TableReader:
    """The state of `read_table` between pieces: the current line, the rows so far."""

    def __init__(self, max_values: int, keys: frozenset, limit_note: str):
        self.max_values, self.keys, self.limit_note = max_values, keys, limit_note
        self.header: dict[str, str] = {}
        self.values = array("d")
        self.width: int | None = None  # values per row (the first data row's)
        self.rows = 0
        self.delimiter: str | None = None  # decided by the first data line: "," or ";" if it holds one, else whitespace
        self.names_allowed = True  # the first data line may be column names
        self.number = 0  # line number
        self.line_mode: str | None = None  # of the current line: "data", "names", "skip"; None between lines
        self.carry = ""  # the start of a field cut by the end of a piece
        self.row_values = 0
        self.seen_text = False  # the current line has more than whitespace
        self.bad_name: str | None = None  # in a names line: the first field that is not a number

    def read(self, piece: str) -> None:
        if "\x00" in piece:
            line = self.number + (self.line_mode is None)
            raise InputError(f"cannot read the file as UTF-8 text: line {line} holds a NUL character (a binary file?)")
        ends = piece.endswith("\n")
        if self.line_mode is None:
            self._start_line(piece)
        if self.line_mode != "skip":
            self._fields(piece, ends)
        if ends:
            self._end_line()

    def _start_line(self, piece: str) -> None:
        self.number += 1
        self.row_values, self.seen_text, self.carry, self.bad_name = 0, False, "", None
        head = piece.strip()
        if head.startswith("#"):  # a header line (only its first piece is read)
            key, sep, value = head[1:].partition(":")
            if sep and key.strip().lower() in self.keys:
                self.header[key.strip().lower()] = value.strip()
            self.line_mode = "skip"
            return
        self.line_mode = "data"
        if self.delimiter is None and head:
            self.delimiter = "," if "," in head else (";" if ";" in head else None)

    def _fields(self, piece: str, ends: bool) -> None:
        text = self.carry + piece
        if not self.seen_text and not text.strip():  # blank so far
            self.carry = ""
            return
        self.seen_text = True
        if self.delimiter is None:
            fields = text.split()
            cut = not ends and not text[-1:].isspace()
        else:
            fields = text.split(self.delimiter)
            cut = not ends
        self.carry = fields.pop().lstrip() if cut and fields else ""
        if len(self.carry) > MAX_FIELD_CHARS:
            raise InputError(f"line {self.number}: a value of more than {MAX_FIELD_CHARS} characters is not a number")
        if self.line_mode == "names":
            self._names(fields)
            return
        try:
            numbers = [float(f) for f in fields]
        except ValueError:
            bad = next(f for f in fields if not is_number(f))
            if self.names_allowed and self.row_values == 0 and not any(is_number(f) for f in fields):
                self.line_mode, self.bad_name = "names", bad  # a first line of column names, unless a number follows
                return
            raise InputError(f"line {self.number}: cannot read {bad.strip()!r} as a number") from None
        self.values.extend(numbers)
        self.row_values += len(numbers)
        if len(self.values) > self.max_values:
            raise InputError(f"the file holds more than {self.max_values:,} numbers{self.limit_note}")

    def _names(self, fields) -> None:
        if any(is_number(f) for f in fields):  # a line of names has no number
            assert self.bad_name is not None  # set with line_mode "names"
            raise InputError(f"line {self.number}: cannot read {self.bad_name.strip()!r} as a number")

    def _end_line(self) -> None:
        mode, self.line_mode = self.line_mode, None
        if mode == "skip" or not self.seen_text:
            return
        self.names_allowed = False
        if mode == "names":
            return
        if self.width is None:
            self.width = self.row_values
        elif self.row_values != self.width:
            raise InputError(f"wrong shape: rows have different numbers of values ({self.width} in the first data row, "
                             f"{self.row_values} in data row {self.rows + 1})")
        self.rows += 1

    def table(self) -> np.ndarray:
        """The numbers read, shape (rows, columns); `InputError` if there are none."""
        if self.line_mode is not None:  # a last line without a newline
            if self.line_mode != "skip":
                self._fields("", True)
            self._end_line()
        if not self.rows:
            raise InputError("no numbers in the file")
        assert self.width is not None  # set by the first data row
        return np.frombuffer(self.values, dtype=float).reshape(self.rows, self.width)


def is_number(text: str) -> bool:
    """Whether ``text`` reads as a float."""
    try:
        float(text)
    except ValueError:
        return False
    return True
