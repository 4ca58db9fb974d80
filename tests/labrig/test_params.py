"""labrig.params: one declaration per parameter gives its check, its file kind and its file comment."""

import math
from dataclasses import dataclass
from typing import ClassVar

import pytest

from labrig.params import Param, check_fields, file_schema
from labrig.validate import InputError, typed

WIDTH = Param("float", 0.0, 1e6, low_open=True, unit="px", doc="board width")
SIGMA = Param("float", 0.0, 1.0, high_open=True, doc="spread")
DOTS = Param("int", 0, 1_000_000, doc="dots")
MODEL = Param("str", choices=("thesis", "hamaker"), doc="pull law")
THREADS = Param("int", choices=(1, 2), doc="threads")
CLOSED = Param("bool", doc="walls")
NAME = Param("str", high=10, doc="label")
POINT = Param("float2", -5.0, 5.0, unit="px", doc="point")
HASH = Param("pair", optional=True, doc="hash", unset="a tree",
             parts=(Param("float", 0.0, 10.0, low_open=True, unit="px", doc="cell size"), Param("int", 1, 9, doc="count")))
GAP = Param("float", 0.0, math.inf, low_open=True, unit="s", optional=True, doc="gap", rule="above min", unset="none")
TIMES = Param("floats", 0.0, 10.0, unit="s", most=3, doc="times")
SCALES = Param("float2s", 0.0, 100.0, unit="nm", most=2, doc="scales")
RECORD = Param("either", doc="rows", parts=(Param("int", 1, 50, doc="a count"), Param("floats", 0.0, 10.0, doc="times")))


@pytest.mark.parametrize("param, value, message", [
    (WIDTH, 0, r"^w must be in \(0, 1e6\] px, got 0.0$"),
    (WIDTH, "1", r"^w must be a number in \(0, 1e6\] px, got '1'$"),
    (SIGMA, 1.0, r"^w must be in \[0, 1\), got 1.0$"),
    (DOTS, 2.5, r"^w must be an integer in \[0, 1,000,000\], got 2.5$"),
    (MODEL, "java", r"^w must be one of 'thesis', 'hamaker', got 'java'$"),
    (THREADS, 3, r"^w must be one of 1, 2, got 3$"),
    (CLOSED, 1, r"^w must be true or false, got 1$"),
    (NAME, "x" * 11, r"^w must be a non-empty string of at most 10 characters"),
    (POINT, [1.0, 9.0], r"^w must hold numbers in \[-5, 5\] px, got 9.0$"),
    (HASH, "big", r"^w must be \(cell size px, count\), got 'big'$"),
    (HASH, (0.0, 3), r"^w cell size must be in \(0, 10\] px, got 0.0$"),
    (HASH, (1.0, 30), r"^w count must be an integer in \[1, 9\], got 30$"),
    (GAP, 0, r"^w must be > 0 s, got 0.0$"),
    (TIMES, [1.0, 11.0], r"^w must hold numbers in \[0, 10\] s, got 11.0$"),
    (TIMES, [1.0] * 4, r"^w must hold at most 3 numbers, got 4$"),
    (TIMES, "1 2", r"^w must be a list of at most 3 numbers, each number in \[0, 10\], got '1 2'$"),
    (SCALES, [], r"^w must be a list of at most 2 \[number, number\] pairs"),
    (SCALES, [[1.0, 2.0], [3.0]], r"^w\[1\] must be 2 numbers \(nm\), got \[3.0\]$"),
    (SCALES, [[1.0, 2.0]] * 3, r"^w must hold at most 2 pairs, got 3$"),
    (RECORD, 0, r"^w must be an integer in \[1, 50\], got 0$"),
    (RECORD, [20.0], r"^w must hold numbers in \[0, 10\], got 20.0$"),
    (RECORD, "all", r"^w must be a count \(integer in \[1, 50\]\) or times \(a list of numbers, each number in "
                    r"\[0, 10\]\), got 'all'$"),
    (RECORD, True, r"^w must be a count"),
])
def test_a_check_refuses_in_the_words_of_labrig_validate(param, value, message):
    with pytest.raises(InputError, match=message):
        param.check("w", value)


def test_a_check_returns_the_plain_value():
    assert WIDTH.check("w", 3) == 3.0 and type(WIDTH.check("w", 3)) is float
    assert POINT.check("w", [1, 2]) == (1.0, 2.0) and HASH.check("w", [2, 3]) == (2.0, 3)
    assert HASH.check("w", None) is None and GAP.check("w", None) is None and CLOSED.check("w", True) is True
    with pytest.raises(InputError, match="w must be a number"):
        WIDTH.check("w", None)  # not optional
    assert TIMES.check("w", [1, 2.5]) == [1.0, 2.5] and TIMES.check("w", []) == []
    assert SCALES.check("w", ((1, 2), (3, 4))) == [[1.0, 2.0], [3.0, 4.0]]
    assert RECORD.check("w", 7) == 7 and RECORD.check("w", [0, 1]) == [0.0, 1.0]  # the value's kind chooses


def test_the_comment_states_what_the_unit_and_the_range():
    assert WIDTH.comment() == "board width: px, in (0, 1e6]"
    assert SIGMA.comment() == "spread: unitless, in [0, 1)"
    assert DOTS.comment() == "dots: unitless, integer in [0, 1,000,000]"
    assert MODEL.comment() == 'pull law: one of "thesis", "hamaker"'
    assert THREADS.comment() == "threads: one of 1, 2"
    assert CLOSED.comment() == "walls: true or false"
    assert NAME.comment() == "label: text of at most 10 characters"
    assert POINT.comment() == "point: px, 2 numbers, each in [-5, 5]"
    assert HASH.comment() == "hash [cell size, count]: px, in (0, 10]; unitless, integer in [1, 9]; unset: a tree"
    assert GAP.comment() == "gap: s, > 0; above min; unset: none"
    assert TIMES.comment() == "times: s, a list of at most 3 numbers, each number in [0, 10]"
    assert RECORD.comment() == "rows: a count (integer in [1, 50]) or times (a list of numbers, each number in [0, 10])"


def test_the_file_kind_is_what_labrig_validate_typed_reads():
    assert [p.file_kind for p in (WIDTH, DOTS, MODEL, THREADS, CLOSED, POINT, HASH, GAP)] == \
        ["float", "int", "str", "int", "bool", "float2", "pair?", "float?"]
    assert typed("k", [2.0, 3], HASH.file_kind) == (2.0, 3) and typed("k", False, GAP.file_kind) is None
    assert file_schema({"width": WIDTH}) == {"width": ("float", "board width: px, in (0, 1e6]")}
    assert (TIMES.file_kind, SCALES.file_kind, RECORD.file_kind) == ("floats", "float2s", "int|floats")
    assert typed("k", [[1, 2]], SCALES.file_kind) == [[1.0, 2.0]] and typed("k", 3, RECORD.file_kind) == 3


def test_a_declaration_must_be_complete():
    with pytest.raises(ValueError, match="kind must be one of"):
        Param("complex")
    with pytest.raises(ValueError, match="two parts"):
        Param("pair")
    with pytest.raises(ValueError, match="choices or a longest length"):
        Param("str")
    with pytest.raises(ValueError, match="two or more parts of different kinds"):
        Param("either", parts=(DOTS, DOTS))
    with pytest.raises(ValueError, match="only 'pair' and 'either' Params take parts"):
        Param("floats", parts=(DOTS, WIDTH))


@dataclass(frozen=True)
class Box:
    width: float = 1.0
    closed: bool = True
    label: str = "free"  # not declared: not checked

    PARAMS: ClassVar[dict] = {"width": WIDTH, "closed": CLOSED}

    def __post_init__(self):
        check_fields(self, self.PARAMS, "box.")


def test_check_fields_checks_and_stores_the_declared_fields_of_a_frozen_dataclass():
    box = Box(width=2, closed=True, label="")
    assert box.width == 2.0 and type(box.width) is float and box.label == ""
    with pytest.raises(InputError, match=r"^box.width must be in \(0, 1e6\] px, got -1.0$"):
        Box(width=-1.0)
