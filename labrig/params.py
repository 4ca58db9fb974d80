"""Parameter declarations: each parameter's kind, range, unit and meaning written once.

A `Param` declares one parameter of a class. The class checks its values with `Param.check` (through
`labrig.validate`, so the messages read as everywhere else), and a saved parameter file states the
same declaration in the comment of the key (`Param.comment`); the file reader checks the TOML kind
(`Param.file_kind`). Change a bound in the declaration and both follow::

    >>> WIDTH = Param("float", 0.0, 1e6, low_open=True, unit="px", doc="board width")
    >>> WIDTH.check("board.width", 600)
    600.0
    >>> WIDTH.comment()
    'board width: px, in (0, 1e6]'
    >>> WIDTH.check("board.width", 0)
    Traceback (most recent call last):
    ...
    labrig.validate.InputError: board.width must be in (0, 1e6] px, got 0.0

Rules between parameters (a gap above another, a bound that needs the time step) stay in the code
that checks them; a declaration names them in words (``rule``) so the file comment states them too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .tomlfile import toml_value
from .validate import InputError, choice, count, flag, interval, real, reals, text, typed

__all__ = ["KINDS", "Param", "check_fields", "file_schema"]

#: Kinds of parameter: the plain value each check returns and the TOML kind files hold
#: (`labrig.validate.typed`).
KINDS = {
    "float": "float",  # a finite number in [low, high]
    "int": "int",  # an integer in [low, high]
    "str": "str",  # one of ``choices``, or non-blank text of at most ``high`` characters
    "bool": "bool",  # true or false
    "float2": "float2",  # two finite numbers, each in [low, high]
    "pair": "pair",  # (number, integer), each checked by its declaration in ``parts``
    "floats": "floats",  # a list of finite numbers, each in [low, high], at most ``most`` of them
    "float2s": "float2s",  # a non-empty list of number pairs, each number in [low, high], at most ``most``
    "either": "",  # one of the declarations in ``parts``, chosen by the value's kind (a count or a list)
}


@dataclass(frozen=True)
class Param:
    """One parameter: its kind, range, unit and meaning.

    Parameters
    ----------
    kind : str
        One of `KINDS`.
    low, high : float
        Bounds of a number (infinite: none); for ``"str"``, ``high`` is the longest text, characters.
    low_open, high_open : bool
        Exclude the bound itself (``"float"`` only).
    unit : str
        Unit of a number (``"px"``, ``"s"``, ``"1/s"``); empty: unitless.
    choices : tuple
        The values allowed, for a ``"str"`` or ``"int"`` parameter that takes one of a few.
    optional : bool
        None is accepted and means ``unset``.
    doc : str
        What the parameter is, a few words (the start of the file comment).
    rule : str
        A further condition on the value, checked in code (e.g. ``"above min_gap"``), stated in the comment.
    unset : str
        What None means (optional parameters), stated in the comment.
    parts : tuple of Param
        The declarations of the two members of a ``"pair"`` (each with its ``doc``), or the alternatives of an
        ``"either"`` (of different kinds: the value's kind chooses).
    most : int
        Most items of a ``"floats"`` or ``"float2s"`` list (0: no limit beyond memory).
    """

    kind: str
    low: float = -math.inf
    high: float = math.inf
    low_open: bool = False
    high_open: bool = False
    unit: str = ""
    choices: tuple = ()
    optional: bool = False
    doc: str = ""
    rule: str = ""
    unset: str = ""
    parts: tuple = ()
    most: int = 0

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"Param kind must be one of {', '.join(KINDS)}, got {self.kind!r}")
        if self.kind == "pair" and len(self.parts) != 2:
            raise ValueError("a 'pair' Param takes two parts")
        if self.kind == "either" and (len(self.parts) < 2 or len({p.kind for p in self.parts}) != len(self.parts)):
            raise ValueError("an 'either' Param takes two or more parts of different kinds")
        if self.kind not in ("pair", "either") and self.parts:
            raise ValueError("only 'pair' and 'either' Params take parts")
        if self.kind == "str" and not self.choices and math.isinf(self.high):
            raise ValueError("a 'str' Param takes choices or a longest length (high)")
        if self.kind == "int" and not self.choices and not math.isfinite(self.low):
            raise ValueError("an 'int' Param takes a finite lowest value (low)")

    @property
    def file_kind(self) -> str:
        """The kind a parameter file holds (`labrig.validate.typed`): ``"float"``, ``"int?"`` (may be unset), ..."""
        plain = "|".join(KINDS[p.kind] for p in self.parts) if self.kind == "either" else KINDS[self.kind]
        return plain + ("?" if self.optional else "")

    def check(self, key: str, value):
        """``value`` in its plain form if this declaration allows it (None if optional); `InputError` naming
        ``key`` (``"board.width"``) and the allowed range or choices otherwise."""
        if value is None and self.optional:
            return None
        if self.choices:
            return choice(key, value, self.choices)
        if self.kind == "float":
            return real(key, value, self.low, self.high, low_open=self.low_open, high_open=self.high_open,
                        unit=self.unit)
        if self.kind == "int":
            return count(key, value, int(self.low), None if math.isinf(self.high) else int(self.high))
        if self.kind == "str":
            return text(key, value, int(self.high))
        if self.kind == "bool":
            return flag(key, value)
        if self.kind == "float2":
            return reals(key, value, 2, self.low, self.high, unit=self.unit)
        if self.kind == "either":
            for part in self.parts:
                try:
                    typed(key, value, part.file_kind.rstrip("?"))
                except InputError:
                    continue
                return part.check(key, value)
            raise InputError(f"{key} must be {self.bounds()}, got {value!r}")
        if self.kind in ("floats", "float2s"):
            return self._check_list(key, value)
        first, second = self.parts  # "pair"
        if isinstance(value, (str, bytes, dict)) or not hasattr(value, "__len__") or len(value) != 2:
            labels = ", ".join(f"{p.doc} {p.unit}".strip() for p in self.parts)
            raise InputError(f"{key} must be ({labels}), got {value!r}")
        return first.check(f"{key} {first.doc}", value[0]), second.check(f"{key} {second.doc}", value[1])

    def _check_list(self, key: str, value) -> list:
        """A ``"floats"`` or ``"float2s"`` value as a list (of lists)."""
        pairs = self.kind == "float2s"
        if isinstance(value, (str, bytes, dict)) or not hasattr(value, "__len__") or (pairs and not len(value)):
            raise InputError(f"{key} must be {self.bounds()}, got {value!r}")
        if self.most and len(value) > self.most:
            raise InputError(f"{key} must hold at most {self.most:,} {'pairs' if pairs else 'numbers'}, "
                             f"got {len(value):,}")
        if not pairs:
            return list(reals(key, value, None, self.low, self.high, unit=self.unit))
        return [list(reals(f"{key}[{k}]", v, 2, self.low, self.high, unit=self.unit)) for k, v in enumerate(value)]

    def bounds(self) -> str:
        """The allowed values in words, as the messages of `check` say them: ``"in (0, 1e6]"``, ``"integer >= 1"``,
        ``"one of "thesis", "hamaker""``, ``"true or false"``."""
        if self.choices:
            return "one of " + ", ".join(toml_value(c) for c in self.choices)
        if self.kind == "float":
            allowed = interval(self.low, self.high, self.low_open, self.high_open)
            return "any finite number" if allowed == "finite" else allowed
        if self.kind == "int":
            return f"integer >= {self.low}" if math.isinf(self.high) else f"integer in [{self.low}, {self.high:,}]"
        if self.kind == "str":
            return f"text of at most {int(self.high):,} characters"
        if self.kind == "bool":
            return "true or false"
        if self.kind == "float2":
            return f"2 numbers, each {interval(self.low, self.high)}"
        if self.kind in ("floats", "float2s"):
            items = "numbers" if self.kind == "floats" else "[number, number] pairs"
            most = f"at most {self.most:,} " if self.most else ""
            return f"a list of {most}{items}, each number {interval(self.low, self.high)}"
        if self.kind == "either":
            return " or ".join(f"{p.doc} ({p.bounds()})" for p in self.parts)
        return "; ".join(f"{p.unit or 'unitless'}, {p.bounds()}" for p in self.parts)

    def comment(self) -> str:
        """The file comment of the parameter: what it is, its unit and its range (and rule, and what unset means).

        ``"board width: px, in (0, 1e6]"``, ``"fraction of the mean diameter: unitless, in [0, 1)"``,
        ``"pull law: one of "thesis", "hamaker""``.
        """
        if self.kind == "pair":
            head = f"{self.doc} [{', '.join(p.doc for p in self.parts)}]: {self.bounds()}"
        elif self.kind in ("float", "int", "float2", "floats", "float2s") and not self.choices:
            head = f"{self.doc}: {self.unit or 'unitless'}, {self.bounds()}"
        else:
            head = f"{self.doc}: {self.bounds()}"
        return head + (f"; {self.rule}" if self.rule else "") + (f"; unset: {self.unset}" if self.optional else "")


def check_fields(obj, params: dict, prefix: str = "") -> None:
    """Check the fields ``params`` declares on the frozen dataclass ``obj``, in the order of ``params``, and
    store each in its plain form; `InputError` naming ``prefix + field`` (``"board.width"``) otherwise."""
    for name, param in params.items():
        object.__setattr__(obj, name, param.check(f"{prefix}{name}", getattr(obj, name)))


def file_schema(params: dict) -> dict:
    """``{key: (file kind, comment)}`` of the declarations ``params``: the schema `labrig.tomlfile.top_level`
    takes."""
    return {key: (param.file_kind, param.comment()) for key, param in params.items()}
