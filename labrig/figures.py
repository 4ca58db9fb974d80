"""Figures written to files: atomically, at a bounded resolution.

>>> from matplotlib.figure import Figure
>>> fig = Figure(figsize=(4, 3))
>>> save_figure(fig, "run.png", dpi=150)
PosixPath('run.png')
>>> save_figure(fig, "huge.png", dpi=1e5)
Traceback (most recent call last):
...
labrig.validate.InputError: dpi must be in (0, ...], got 100000.0
"""

from __future__ import annotations

import os
from pathlib import Path

from matplotlib.figure import Figure

from .files import atomic_path
from .validate import InputError, real

__all__ = ["MAX_DPI", "MAX_PIXELS", "check_dpi", "save_figure"]

#: Largest resolution of a picture, dots per inch: print quality (a 6 in board is 7,200 px a side).
MAX_DPI = 1200.0
#: Most pixels of a picture (a 6 x 6 in board at `MAX_DPI` is 5.2e7; matplotlib's Agg renderer stops at 65,536
#: px a side).
MAX_PIXELS = 2e8


def check_dpi(dpi) -> float:
    """``dpi`` as a float in (0, `MAX_DPI`]; `InputError` naming it otherwise."""
    return real("dpi", dpi, 0.0, MAX_DPI, low_open=True)


def save_figure(fig: Figure, path: str | os.PathLike, dpi: float = 100, format: str | None = None) -> Path:
    """Write ``fig`` to ``path`` (format from the suffix unless given) at ``dpi``, atomically; returns the path.

    Raises
    ------
    labrig.validate.InputError
        If ``dpi`` is not in (0, `MAX_DPI`] or the picture would have more than `MAX_PIXELS` pixels.
    """
    dpi = check_dpi(dpi)
    width, height = fig.get_size_inches()
    pixels = width * height * dpi * dpi
    if pixels > MAX_PIXELS:
        raise InputError(f"a {width:g} x {height:g} in figure at dpi = {dpi:g} has {pixels:.3g} pixels, more than the "
                         f"{MAX_PIXELS:.3g} allowed: lower dpi")
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format=format or path.suffix.lstrip(".") or "png", dpi=dpi)
    return path
