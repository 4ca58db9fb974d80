"""Error against time: is the default setting on the Pareto front, and the plot that shows it.

A knob's settings are `Point` s (time, error). The default is *dominated* when another
setting is no worse on both axes and clearly better on one, with the machine's timing noise
taken into account (timings on this shared machine vary 20-40 % between runs, less within one
interleaved run):

* "no worse in time" means at most `TIME_TIE` slower, "clearly faster" at least `TIME_NOISE` faster;
* "no worse in error" means at most the default's error, "clearly better" at most half of it;
* errors below the case's ``floor`` (round-off) count as equal, and so do errors whose difference
  is within twice their combined standard error (for errors that are means over seeds).
"""

from __future__ import annotations

import textwrap
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from matplotlib.ticker import FuncFormatter, LogLocator

#: Relative time difference treated as a tie (noise within one interleaved run).
TIME_TIE = 0.15
#: Relative time saving that counts as clearly faster.
TIME_NOISE = 0.25


@dataclass
class Point:
    """One setting of a knob: its label, cost and error, measured in the same run."""

    label: str
    time: float
    error: float
    default: bool = False
    error_se: float = 0.0


def dominates(a: Point, b: Point, floor: float = 0.0) -> bool:
    """True when ``a`` is no worse than ``b`` on both axes and clearly better on one (see module doc)."""
    ea, eb = max(a.error, floor), max(b.error, floor)
    noise = 2.0 * float(np.hypot(a.error_se, b.error_se))
    no_worse = a.time <= b.time * (1 + TIME_TIE) and ea <= eb + noise
    clearly_better = a.time <= b.time * (1 - TIME_NOISE) or (ea <= 0.5 * eb and eb - ea > noise)
    return no_worse and clearly_better


def verdict(points: Sequence[Point], floor: float = 0.0) -> str:
    """'on the front', or which settings dominate the default and by how much."""
    default = next((p for p in points if p.default), None)
    if default is None:
        return "no default among these settings"
    better = [p for p in points if p is not default and dominates(p, default, floor)]
    if not better:
        return "on the front"
    return "dominated by " + ", ".join(
        f"{p.label} ({p.time / default.time:.2f}x time, {max(p.error, floor) / max(default.error, floor):.2g}x error)"
        for p in better)


def plot(ax, points: Sequence[Point], *, title: str, xlabel: str, ylabel: str, floor: float = 0.0,
         reference: Sequence[Point] = (), reference_label: str = "") -> None:
    """Error (log) against time (log), each point labelled, the default a red star; ``reference`` in grey."""
    if reference:
        ax.plot([p.time for p in reference], [max(p.error, floor) for p in reference], "o-", color="0.7",
                ms=3, lw=1, label=reference_label, zorder=1)
    t = np.array([p.time for p in points])
    e = np.array([max(p.error, floor) for p in points])
    ax.errorbar(t, e, yerr=[p.error_se for p in points], fmt="o-", color="C0", ms=4, lw=1, capsize=2, zorder=2)
    for p, x, y in zip(points, t, e):
        ax.annotate(p.label, (x, y), textcoords="offset points", xytext=(4, 3), fontsize=7)
        if p.default:
            ax.plot([x], [y], "*", color="red", ms=13, zorder=3, label="default")
    if floor > 0 and e.min() <= 10 * floor:
        ax.axhline(floor, color="0.8", lw=0.8, ls=":", zorder=0, label="round-off floor")
    ax.set_xscale("log")
    ax.set_yscale("log")
    short = FuncFormatter(lambda value, _: f"{value:g}")
    ax.xaxis.set_major_formatter(short)
    ax.xaxis.set_minor_locator(LogLocator(subs=(2.0, 5.0)))
    ax.xaxis.set_minor_formatter(short)
    ax.set_xlabel(xlabel, fontsize=8)
    ax.set_ylabel(ylabel, fontsize=8)
    ax.set_title(f"{title}\n" + textwrap.fill(verdict(points, floor), 60), fontsize=8)
    ax.tick_params(which="both", labelsize=7)
    ax.grid(True, which="both", alpha=0.25)
    ax.legend(fontsize=6, loc="best")
