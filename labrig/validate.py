"""Checking what people give: one function per kind of value, errors that name the key and the range.

Every check returns the value in its plain form (``float``, ``int``, ``str``, ``bool``, a tuple or a
read-only array) or raises `InputError` with one line that names the key (``deposition.sigma``),
what is allowed and what was given::

    >>> real("deposition.sigma", 0.05, 0.0, 1.0, high_open=True)
    0.05
    >>> real("deposition.sigma", 2.0, 0.0, 1.0, high_open=True)
    Traceback (most recent call last):
    ...
    labrig.validate.InputError: deposition.sigma must be in [0, 1), got 2.0

Booleans are not numbers here, strings are not numbers, and complex numbers are refused (never
silently cut to their real part). Counts and sizes have upper bounds as well as lower ones, so that
nothing is allocated for a typo (`count`, `within_memory`).

`InputError` is a ``ValueError``: code that catches ``ValueError`` keeps working, and the command
lines (`labrig.cli.run_main`) report it in one line, while any other exception is a bug and keeps
its traceback.

The module imports numpy only where an array or a generator is asked for, so that a command line checks
its arguments without loading it.
"""

from __future__ import annotations

import math
import numbers
import os
import sys
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np

__all__ = ["InputError", "number", "interval", "is_bool", "is_real", "real", "count", "seed", "generator", "choice", "flag", "text", "reals",
           "array", "typed", "within_memory", "available_memory", "printable", "MAX_SEED"]

#: Largest seed accepted (numpy's generators take any integer >= 0; this keeps seeds within 64 bits).
MAX_SEED = 2**63 - 1


class InputError(ValueError):
    """Bad input from a person or a file: reported in one line, never as a traceback."""


def number(value: float) -> str:
    """A bound as it reads in a message: ``0.25``, ``1000``, ``1e6``, ``1e-7``."""
    return f"{value:g}".replace("e+0", "e").replace("e+", "e").replace("e-0", "e-")


def interval(low: float = -math.inf, high: float = math.inf, low_open: bool = False,
             high_open: bool = False) -> str:
    """How an allowed range reads in a message: ``"> 0"``, ``">= 1"``, ``"<= 5"`` or ``"in [0, 1)"``."""
    if math.isinf(high):
        return f"{'>' if low_open else '>='} {number(low)}" if math.isfinite(low) else "finite"
    if math.isinf(low):
        return f"{'<' if high_open else '<='} {number(high)}"
    return f"in {'(' if low_open else '['}{number(low)}, {number(high)}{')' if high_open else ']'}"


def is_bool(value) -> bool:
    """True for ``True``, ``False`` and numpy's booleans (a numpy boolean exists only once numpy is loaded)."""
    if isinstance(value, bool):
        return True
    numpy = sys.modules.get("numpy")
    return numpy is not None and isinstance(value, numpy.bool_)


def is_real(value) -> bool:
    """True for a real number (int, float, numpy scalars); False for booleans, strings, complex numbers."""
    return isinstance(value, numbers.Real) and not is_bool(value)


def real(name: str, value, low: float = -math.inf, high: float = math.inf, *, low_open: bool = False,
         high_open: bool = False, unit: str = "") -> float:
    """``value`` as a finite float in the range; `InputError` naming ``name`` otherwise.

    Parameters
    ----------
    name : str
        The key as the person wrote it (``"board.width"``, ``"ThermalKicks.scale"``).
    low, high : float
        Bounds; infinite bounds mean no bound (the value must still be finite).
    low_open, high_open : bool
        Exclude the bound itself.
    unit : str
        Appended to the range in the message (``"px"``, ``"nm"``, ``"s"``).
    """
    number = is_real(value)
    ok = number and math.isfinite(value)
    if ok:
        value = float(value)
        ok = (value > low if low_open else value >= low) and (value < high if high_open else value <= high)
    if not ok:
        allowed = interval(low, high, low_open, high_open)
        what = "a finite number" if allowed == "finite" else (allowed if number else f"a number {allowed}")
        raise InputError(f"{name} must be {what}{' ' + unit if unit else ''}, got {value!r}")
    return value


def count(name: str, value, low: int = 0, high: int | None = None) -> int:
    """``value`` as an int in ``[low, high]``; `InputError` naming ``name`` and the range otherwise."""
    ok = isinstance(value, numbers.Integral) and not is_bool(value)
    if ok:
        value = int(value)
        ok = value >= low and (high is None or value <= high)
    if not ok:
        allowed = f">= {low}" if high is None else f"in [{low}, {high:,}]"
        raise InputError(f"{name} must be an integer {allowed}, got {value!r}")
    return value


def seed(name: str, value) -> int:
    """A random seed: an integer in ``[0, MAX_SEED]``."""
    return count(name, value, 0, MAX_SEED)


def generator(name: str, rng) -> np.random.Generator:
    """A numpy random Generator from what people pass: a Generator (used as is), a SeedSequence, an
    integer seed in [0, `MAX_SEED`] or None (fresh entropy)."""
    import numpy as np

    if isinstance(rng, np.random.Generator):
        return rng
    if rng is None or isinstance(rng, np.random.SeedSequence):
        return np.random.default_rng(rng)
    if isinstance(rng, numbers.Integral) and not is_bool(rng):
        return np.random.default_rng(seed(name, rng))
    raise InputError(f"{name} must be a numpy Generator, a SeedSequence, an integer seed >= 0 or None, got {rng!r}")


def choice(name: str, value, allowed):
    """``value`` if it is one of ``allowed`` (compared as written: ``"1"`` is not ``1``)."""
    if not any(value == a and type(value) is type(a) for a in allowed):
        raise InputError(f"{name} must be one of {', '.join(repr(a) for a in allowed)}, got {value!r}")
    return value


def flag(name: str, value) -> bool:
    """``value`` if it is ``True`` or ``False`` (not ``"no"``, not 0)."""
    if not is_bool(value):
        raise InputError(f"{name} must be true or false, got {value!r}")
    return bool(value)


def text(name: str, value, max_length: int = 1000) -> str:
    """A non-blank string of at most ``max_length`` characters."""
    if not (isinstance(value, str) and value.strip() and len(value) <= max_length):
        raise InputError(f"{name} must be a non-empty string of at most {max_length} characters, got {value!r}")
    return value


def reals(name: str, value, n: int | None = None, low: float = -math.inf, high: float = math.inf, *,
          unit: str = "") -> tuple[float, ...]:
    """A sequence of finite numbers in the range (``n`` of them when given), as a tuple of floats."""
    if isinstance(value, (str, bytes, dict)) or not hasattr(value, "__len__") or \
            (n is not None and len(value) != n) or not all(is_real(v) and math.isfinite(v) for v in value):
        what = f"{n} numbers" if n is not None else "a list of numbers"
        raise InputError(f"{name} must be {what}{' (' + unit + ')' if unit else ''}, got {value!r}")
    out = tuple(float(v) for v in value)
    bad = [v for v in out if not low <= v <= high]
    if bad:
        raise InputError(f"{name} must hold numbers {interval(low, high)}{' ' + unit if unit else ''}, "
                         f"got {bad[0]!r}")
    return out


def array(name: str, value, shape: tuple[int | None, ...], *, limit: float = math.inf,
          max_size: int | None = None) -> np.ndarray:
    """A read-only float64 copy of ``value`` with the given shape (None: any length), finite and real.

    Integer and float arrays are accepted; booleans, strings, complex numbers, dates and objects are
    not. ``limit`` bounds the magnitude of every element and ``max_size`` the number of elements.
    """
    import numpy as np

    if isinstance(value, np.ndarray):
        raw = value
    else:
        try:
            raw = np.asarray(value)
        except (TypeError, ValueError) as exc:  # ragged nested lists
            raise InputError(f"{name} must be an array of numbers: {exc}") from None
    if raw.size == 0 and raw.dtype.kind not in "iuf":
        raw = np.zeros(raw.shape, dtype=np.float64)  # (an empty array of any kind holds no bad value)
    if raw.dtype.kind not in "iuf":
        raise InputError(f"{name} must hold real numbers, got an array of {raw.dtype}")
    if max_size is not None and raw.size > max_size:
        raise InputError(f"{name} has {raw.size:,} values, more than the {max_size:,} allowed")
    arr = np.array(raw, dtype=np.float64)
    if arr.size == 0 and len(shape) == 2 and shape[1] is not None and arr.ndim < 2:
        arr = arr.reshape(0, shape[1])
    if arr.ndim != len(shape) or any(want is not None and got != want for got, want in zip(arr.shape, shape)):
        want = "(" + ", ".join("N" if s is None else str(s) for s in shape) + ("," if len(shape) == 1 else "") + ")"
        raise InputError(f"{name} must have shape {want}, got {arr.shape}")
    bad = ~np.isfinite(arr) | (np.abs(arr) > limit)
    if bad.any():
        index = tuple(int(i) for i in np.argwhere(bad)[0])
        where = f"[{index[0]}]" if index else ""  # the row: a dot, a point, a segment
        why = "is not finite" if not np.isfinite(arr[index]) else f"exceeds {number(limit)} in magnitude"
        raise InputError(f"{name}{where} {why} ({float(arr[index])!r})")
    arr.setflags(write=False)
    return arr


def available_memory() -> float:
    """Bytes of memory this process can expect to get (MemAvailable on Linux; else the physical memory; inf
    when neither can be read)."""
    try:
        with open("/proc/meminfo") as stream:
            for line in stream:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return float(os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):  # pragma: no cover - no way to tell
        return math.inf


def within_memory(name: str, n_bytes: float, limit_bytes: float) -> None:
    """`InputError` when what ``name`` asks for would need more than ``limit_bytes`` of memory."""
    if n_bytes > limit_bytes:
        raise InputError(f"{name} would need about {n_bytes / 2**30:.3g} GiB of memory, more than the "
                         f"{limit_bytes / 2**30:.3g} GiB allowed")


#: Control characters (C0, DEL, C1) and how `printable` writes them.
_ESCAPES = {code: {9: "\\t", 10: "\\n", 13: "\\r"}.get(code, f"\\x{code:02x}")
            for code in [*range(32), *range(127, 160)]}


def printable(text) -> str:
    """``text`` (``str(text)``) with its control characters written as escapes (``\\x1b``, ``\\x07``, ``\\n``, ...).

    Names and messages from files are data and may hold any character; printed raw, an ESC or a CR
    would drive the terminal (colours, cursor moves, an overwritten line). Whatever repeats such text
    on a terminal prints ``printable(text)`` instead::

        >>> printable("dots\\x1b[2J\\r")
        'dots\\\\x1b[2J\\\\r'
    """
    return str(text).translate(_ESCAPES)


# -- value kinds of files (TOML) -------------------------------------------------------------

_KINDS = {
    "float": "a number",
    "int": "an integer",
    "str": "a string",
    "bool": "true or false",
    "floats": "a list of numbers",
    "float2": "a list of two numbers",
    "float2s": "a non-empty list of [number, number] pairs",
    "pair": "a list [number, integer]",
}


def _as_kind(value, kind: str):
    """``value`` in the plain form of ``kind``, or None if it is not of that kind."""
    if kind == "float":
        return float(value) if is_real(value) else None
    if kind == "int":
        return int(value) if isinstance(value, numbers.Integral) and not is_bool(value) else None
    if kind == "str":
        return value if isinstance(value, str) else None
    if kind == "bool":
        return bool(value) if is_bool(value) else None
    if not isinstance(value, (list, tuple)):
        return None
    if kind == "floats":
        return [float(v) for v in value] if all(is_real(v) for v in value) else None
    if kind == "float2":
        return [float(v) for v in value] if len(value) == 2 and all(is_real(v) for v in value) else None
    if kind == "float2s":
        pairs = [_as_kind(p, "float2") for p in value]
        return pairs if value and all(p is not None for p in pairs) else None
    if kind == "pair":
        ok = len(value) == 2 and is_real(value[0]) and _as_kind(value[1], "int") is not None
        return (float(value[0]), int(value[1])) if ok else None
    raise KeyError(kind)


def typed(key: str, value, kind: str):
    """``value`` checked against a file value ``kind``; `InputError` naming the full ``key`` otherwise.

    Kinds: ``"float"``, ``"int"``, ``"str"``, ``"bool"``, ``"floats"`` (a list of numbers),
    ``"float2"`` (two numbers), ``"float2s"`` (a list of number pairs), ``"pair"`` (``[number,
    integer]``); alternatives joined by ``"|"`` (``"int|floats"``: a count or a list); a trailing
    ``"?"`` marks a key that may be unset (None; ``false`` in a file, where a missing key would take a
    set default). Floats come back as float (an integer written for a number is a number), lists as
    lists. Only the kind is checked here, not the range.
    """
    optional = kind.endswith("?")
    if optional and (value is None or value is False):
        return None
    kinds = kind.rstrip("?").split("|")
    for plain in kinds:
        out = _as_kind(value, plain)
        if out is not None:
            return out
    raise InputError(f"{key} must be {' or '.join(_KINDS[k] for k in kinds)}, got {value!r}")
