"""One reproduced thesis result: what the thesis says, what we measured, and the verdict."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

#: The verdicts an item may reach.
VERDICTS = ("reproduced", "partly reproduced", "differs", "the thesis was wrong", "engines agree", "engines differ")


@dataclass
class Quote:
    """A sentence of the thesis and its line in ``seed/thesis.txt``."""

    line: int
    text: str


@dataclass
class Item:
    """A thesis figure or table, reproduced.

    Attributes
    ----------
    key : str
        Short name (``"fig2-4"``), what ``--only`` takes.
    title : str
        Heading of its section.
    thesis : list of Quote
        What the thesis shows or states.
    results : list
        `benchmarks.report` results (``Table``, ``Figure``, ``Note``).
    verdict : str
        One of `VERDICTS`.
    why : str
        The measured reason for the verdict.
    wall_s : float
        Wall time of the item's own work (the shared film runs are counted once, in their own row).
    """

    key: str
    title: str
    thesis: list[Quote]
    results: list = field(default_factory=list)
    verdict: str = "differs"
    why: str = ""
    wall_s: float = 0.0

    def __post_init__(self) -> None:
        if self.verdict not in VERDICTS:
            raise ValueError(f"verdict must be one of {VERDICTS}, got {self.verdict!r}")


def mean_se(values) -> tuple[float, float]:
    """Mean and standard error of the finite ``values`` (nan SE for fewer than two)."""
    values = np.asarray(values, dtype=float)
    values = values[np.isfinite(values)]
    if not values.size:
        return math.nan, math.nan
    se = float(values.std(ddof=1) / math.sqrt(values.size)) if values.size > 1 else math.nan
    return float(values.mean()), se


def pm(mean: float, se: float, digits: int = 3) -> str:
    """``"0.735 +- 0.012"`` (the SE left out when it is nan)."""
    return f"{mean:.{digits}f}" if math.isnan(se) else f"{mean:.{digits}f} +- {se:.{digits}f}"


def apart(a: tuple[float, float], b: tuple[float, float], sigmas: float = 2.0) -> bool:
    """Whether two (mean, SE) differ by more than ``sigmas`` combined standard errors."""
    se = math.hypot(a[1], b[1])
    return bool(math.isfinite(se) and abs(a[0] - b[0]) > sigmas * se)


def make_items(makers: dict, only=None) -> list[Item]:
    """Call each ``makers[key]()`` whose key is in ``only`` (all when None), timing each into ``wall_s``."""
    items = []
    for key, make in makers.items():
        if only is None or key in only:
            start = time.perf_counter()
            item = make()
            item.wall_s = time.perf_counter() - start
            items.append(item)
    return items
