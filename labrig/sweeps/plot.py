"""Mean +- standard error of a sweep's metric against one column, one curve per value of another.

This is how the thesis's sweep figures are drawn (Fig 2-4 and 2-6 a: a
packing metric against sigma, free vs grating or equal vs scaled masses;
Fig 3-13: roughness against the expansion coefficient or the thickness).
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from ..files import atomic_path
from ..jsonfile import read_json
from ..validate import InputError
from .table import is_number, parse_cell, read_table


def _sweep_description(path: str | os.PathLike) -> tuple[list[str], list[str] | None]:
    """The swept columns other than the seed, and the run ids, that the ``sweep.json`` at ``path`` records (none,
    and None, if it is missing).

    Raises
    ------
    labrig.validate.InputError
        If the file is there but unreadable (`labrig.jsonfile.read_json`) or not an object whose ``swept``
        is a list of column names, ``seed_key`` a name or null and ``runs`` a list of ids; the message starts
        with the path.
    """
    try:
        meta = read_json(path, "sweep description")
    except FileNotFoundError:
        return [], None
    swept = meta.get("swept") if isinstance(meta, dict) else None
    seed_key = meta.get("seed_key") if isinstance(meta, dict) else None
    runs = meta.get("runs") if isinstance(meta, dict) else None
    if not (isinstance(swept, list) and all(isinstance(c, str) for c in swept)):
        raise InputError(f"{path}: swept must be a list of column names, got {swept!r:.200}")
    if seed_key is not None and not isinstance(seed_key, str):
        raise InputError(f"{path}: seed_key must be a column name or null, got {seed_key!r:.200}")
    if not (isinstance(runs, list) and all(isinstance(r, str) for r in runs)):
        raise InputError(f"{path}: runs must be a list of run ids, got {runs!r:.200}")
    return [c for c in swept if c != seed_key], runs  # the seeds are averaged over


def _check_whole(path: Path, rows: list[dict], runs: list[str]) -> None:
    """`InputError` unless the table at ``path`` holds one row for each run of its sweep (``runs``, from its
    ``sweep.json``): a table cut short at a row boundary reads as a smaller one."""
    found = [row.get("run") for row in rows]
    if found != runs and found != [parse_cell(run) for run in runs]:  # a CSV's cells are parsed: "1234..." an int
        found = [str(run) for run in found]
        missing, extra = len(set(runs) - set(found)), len(set(found) - set(runs))
        raise InputError(f"{path}: the table has {len(found)} rows for the {len(runs)} runs that sweep.json beside it "
                         f"lists ({missing} missing, {extra} not of that sweep): it was cut short, edited or written "
                         "by another sweep; run the sweep again to rewrite it (finished runs are not run again)")


def _rows(table) -> tuple[list[dict], list[str]]:
    """Rows of ``table`` (a path or a list of dicts) and the swept columns recorded beside a path (a table beside a
    ``sweep.json`` must hold every run it lists)."""
    if isinstance(table, (str, os.PathLike)):
        path = Path(table)
        rows = read_table(path)
        swept, runs = _sweep_description(path.parent / "sweep.json")
        if runs is not None and rows and "run" in rows[0]:
            _check_whole(path, rows, runs)
        return rows, swept
    return list(table), []


def _matches(value, wanted) -> bool:
    wanted = parse_cell(wanted) if isinstance(wanted, str) else wanted
    return value == wanted or str(value) == str(wanted)


def _order(values: list) -> list:
    unique = list(dict.fromkeys(values))
    return sorted(unique) if all(is_number(v) for v in unique) else unique


def summarize(table, metric: str, x: str, group: str | None = None, where: Mapping | None = None) -> list[dict]:
    """Mean and standard error of ``metric`` over the runs that share ``x`` (and ``group``).

    Parameters
    ----------
    table : path or list of dict
        A sweep table (`read_table`) or its rows. Only runs with status ``"ok"``
        and a finite ``metric`` count.
    metric, x : str
        Column names.
    group : str, optional
        One curve per value of this column.
    where : dict, optional
        Keep only rows whose column equals the value (``{"label": "free"}``;
        text values are read like CSV cells: ``"0.05"`` matches 0.05).

    Returns
    -------
    list of dict
        ``group`` (None without one), ``x``, ``n``, ``mean``, ``se`` (the
        standard deviation over ``sqrt(n)``, ddof 1; nan for n = 1), ordered by
        group (first appearance) then x (ascending when numeric).

    Raises
    ------
    ValueError
        If a column is missing, if no row remains, or, for a table read from a
        sweep's output directory (beside its ``sweep.json``), if a swept
        column other than the seed varies among the runs averaged together
        (name it as ``group`` or fix it with ``where``), or if that
        ``sweep.json`` is unreadable or malformed.
    """
    rows, swept = _rows(table)
    where = dict(where or {})
    for name in [metric, x, *([group] if group else []), *where]:
        if rows and name not in rows[0]:
            raise InputError(f"no column {name!r} in the table (columns: {', '.join(rows[0])})")
    rows = [r for r in rows if r.get("status", "ok") == "ok" and all(_matches(r[k], v) for k, v in where.items())]
    if not rows:
        raise InputError(f"no finished run matches {where!r}" if where else "the table has no finished run")
    if not any(is_number(r[metric]) for r in rows):
        raise InputError(f"column {metric!r} holds no numbers to average (e.g. {rows[0][metric]!r})")
    others = [c for c in swept if c not in (x, group, *where) and c in rows[0]]
    cells: dict = {}
    for row in rows:
        cells.setdefault((row[group] if group else None, row[x]), []).append(row)
    summary = []
    for g in _order([key[0] for key in cells]):
        for xv in _order([key[1] for key in cells if key[0] == g]):
            cell = cells[(g, xv)]
            for column in others:
                seen = {json.dumps(r[column], default=str) for r in cell}
                if len(seen) > 1:
                    raise InputError(f"{column!r} varies among the runs at {x} = {xv!r}"
                                     f"{f', {group} = {g!r}' if group else ''} ({', '.join(sorted(seen))}): "
                                     f"choose it as the group or fix it with where")
            values = np.array([r[metric] for r in cell if is_number(r[metric])], dtype=float)
            n = len(values)
            se = float(values.std(ddof=1) / math.sqrt(n)) if n > 1 else math.nan
            summary.append({"group": g, "x": xv, "n": n, "mean": float(values.mean()) if n else math.nan, "se": se})
    return summary


def plot_sweep(table, metric: str, x: str, group: str | None = None, where: Mapping | None = None, *,
               ax=None, **errorbar):
    """Draw `summarize` as error bars (mean +- standard error) on ``ax`` (default: a new figure).

    Numeric ``x`` is drawn to scale, other values at evenly spaced ticks.
    Extra keyword arguments go to ``ax.errorbar``. Returns ``ax``.
    """
    summary = summarize(table, metric, x, group, where)
    if ax is None:
        import matplotlib.pyplot as plt

        ax = plt.subplots(figsize=(6, 4.5))[1]
    xs = _order([s["x"] for s in summary])
    numeric = all(is_number(v) for v in xs)
    options = {"marker": "o", "capsize": 3, **errorbar}
    for g in _order([s["group"] for s in summary]):
        part = [s for s in summary if s["group"] == g]
        at = [s["x"] if numeric else xs.index(s["x"]) for s in part]
        ax.errorbar(at, [s["mean"] for s in part], yerr=[s["se"] for s in part],
                    **{"label": None if group is None else f"{group} = {g}", **options})
    if not numeric:
        ax.set_xticks(range(len(xs)), [str(v) for v in xs])
    ax.set(xlabel=x, ylabel=f"{metric} (mean ± s.e.)")
    if group is not None or "label" in errorbar:
        ax.legend()
    return ax


def save_sweep_plot(path: str | os.PathLike, table, metric: str, x: str, group: str | None = None,
                    where: Mapping | None = None, *, title: str | None = None, dpi: int = 150) -> Path:
    """`plot_sweep` into a PNG at ``path``, written atomically; returns the path."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.4, 4.8), layout="constrained")
    ax = plot_sweep(table, metric, x, group, where, ax=fig.add_subplot())
    if title:
        ax.set_title(title)
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=dpi)
    return path


def summary_lines(summary: Sequence[dict], metric: str, x: str, group: str | None) -> list[str]:
    """The summary as aligned text lines (for the command line)."""
    head = ([group] if group else []) + [x, "n", f"mean {metric}", "s.e."]
    body = [([str(s["group"])] if group else []) + [str(s["x"]), str(s["n"]), f"{s['mean']:.6g}", f"{s['se']:.3g}"]
            for s in summary]
    widths = [max(len(r[k]) for r in [head, *body]) for k in range(len(head))]
    return ["  ".join(cell.rjust(w) for cell, w in zip(r, widths)) for r in [head, *body]]
