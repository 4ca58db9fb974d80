"""Pictures and movies of a board: size colouring (thesis Fig 2-2), PNG, MP4.

Figures are built on matplotlib's object API (no pyplot state) except when
`draw_state` is asked to make its own axes, so that it shows in notebooks.
Files are written atomically: to a temporary file beside the target, then
renamed into place, so a crash never leaves a half-written PNG or MP4.
"""

from __future__ import annotations

import math
import numbers
import time
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import EllipseCollection, LineCollection
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from labrig.files import atomic_path
from labrig.movies import FigureMovie
from labrig.validate import InputError


def size_colours(radii, mean: float | None = None, sigma: float | None = None) -> np.ndarray:
    """RGB colour of each dot by size: large red, mean green, small blue.

    The thesis's colouring (Appendix A, ``addRandomBallAtTop``): with ``d``
    the diameter, ``m`` the mean diameter and ``s = sigma * m``::

        red   = min(1, exp((d - m - s) / s))
        green = exp(-|d - m| / s)
        blue  = min(1, exp(-(d - m + s) / s))

    Parameters
    ----------
    radii : array_like, shape (N,)
        Dot radii, px.
    mean : float, optional
        Mean diameter ``m``, px (> 0). Default: the mean of ``2 * radii``.
    sigma : float, optional
        Standard deviation of the diameters as a fraction of ``mean`` (>= 0).
        Default: the standard deviation of ``2 * radii`` divided by ``mean``.

    Returns
    -------
    ndarray, shape (N, 3)
        RGB in [0, 1]. With equal sizes (``s == 0``) every dot is pure green.
    """
    d = 2.0 * np.asarray(radii, dtype=float).reshape(-1)
    if mean is None:
        mean = float(d.mean()) if d.size else 1.0
    if not (math.isfinite(mean) and mean > 0):
        raise InputError(f"mean must be a diameter > 0 px, got {mean!r}")
    s = (float(d.std()) if d.size else 0.0) if sigma is None else float(sigma) * mean
    if not (math.isfinite(s) and s >= 0):
        raise InputError(f"sigma must be >= 0, got {sigma!r}")
    colours = np.zeros((d.size, 3))
    if s <= 1e-12 * mean:  # equal sizes (up to round-off in the std)
        colours[:, 1] = 1.0
        return colours
    colours[:, 0] = np.minimum(1.0, np.exp((d - mean - s) / s))
    colours[:, 1] = np.exp(-np.abs(d - mean) / s)
    colours[:, 2] = np.minimum(1.0, np.exp(-(d - mean + s) / s))
    return colours


class BoardArtists:
    """The artists of one board on one Axes, created once and then updated."""

    def __init__(self, ax):
        self.ax = ax
        self.dots = self.walls = self.outline = None

    def draw(self, state, colours=None, show_time: bool = True) -> None:
        ax = self.ax
        w, h = (float(v) for v in state.box)
        positions = np.asarray(state.positions, dtype=float).reshape(-1, 2)
        diameters = 2.0 * np.asarray(state.radii, dtype=float)
        walls = np.asarray(getattr(state, "walls", np.zeros((0, 4))), dtype=float).reshape(-1, 2, 2)
        if colours is None:
            colours = size_colours(state.radii)
        if self.dots is None:
            self.outline = Rectangle((0, 0), w, h, fill=False, edgecolor="0.6", linewidth=0.8,
                                     linestyle="--", zorder=1)
            ax.add_patch(self.outline)
            self.walls = LineCollection(walls, colors="black", linewidths=1.5, zorder=3)
            ax.add_collection(self.walls, autolim=False)
            self.dots = EllipseCollection(
                diameters, diameters, np.zeros(len(diameters)), units="xy", offsets=positions,
                offset_transform=ax.transData, facecolors=colours, edgecolors=(0, 0, 0, 0.5),
                linewidths=0.3, zorder=2,
            )
            ax.add_collection(self.dots, autolim=False)
            ax.set_aspect("equal")
        else:
            self.outline.set_width(w)
            self.outline.set_height(h)
            self.walls.set_segments(walls)
            self.dots.set_offsets(positions)
            self.dots.set_widths(diameters)
            self.dots.set_heights(diameters)
            self.dots.set_angles(np.zeros(len(diameters)))
            self.dots.set_facecolor(colours)
        pad = 0.01 * max(w, h)
        ax.set_xlim(-pad, w + pad)
        ax.set_ylim(-pad, h + pad)
        ax.set_title(f"t = {float(getattr(state, 'time', 0.0)):.1f} s" if show_time else "")


def draw_state(state, ax=None, colours=None, show_time: bool = True):
    """Draw a board: outline, walls (black), dots coloured by size.

    Parameters
    ----------
    state : State
        The board; uses ``box``, ``positions``, ``radii`` (px) and, when
        present, ``walls`` (segments, px) and ``time`` (s).
    ax : matplotlib.axes.Axes, optional
        Where to draw. Default: a new pyplot figure (so it shows in notebooks).
    colours : array_like, shape (N, 3) or (N, 4), optional
        Face colour of each dot (any matplotlib colour spec). Default
        `size_colours` of the radii.
    show_time : bool
        Put ``t = 12.3 s`` in the title.

    Returns
    -------
    matplotlib.axes.Axes
        The axes drawn on, in px with equal aspect and y up.
    """
    if ax is None:
        import matplotlib.pyplot as plt

        _, ax = plt.subplots(figsize=(6, 6))
    BoardArtists(ax).draw(state, colours, show_time)
    return ax


def save_png(state, path, dpi: int = 100) -> Path:
    """Write a picture of the board to ``path`` (PNG, 6 x 6 in at ``dpi``), atomically.

    Returns
    -------
    pathlib.Path
        The path written.
    """
    if not (isinstance(dpi, numbers.Real) and dpi > 0):
        raise InputError(f"dpi must be > 0, got {dpi!r}")
    fig = Figure(figsize=(6, 6))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    BoardArtists(ax).draw(state)
    ax.set_xlabel("x (px)")
    ax.set_ylabel("y (px)")
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=dpi)
    return path


class MovieWriter(FigureMovie):
    """Stream board states to an MP4 movie; a writer for `qdots.Simulation.run`.

    Each `write` draws the state on the movie's reused figure (see `FigureMovie`).

    Parameters
    ----------
    path : str or Path
        Output file (``.mp4``).
    every : int
        Simulation steps between frames (>= 1).
    fps : float
        Frames per second of the movie (> 0).
    size_px : int
        Width and height of a frame, pixels (even, >= 16).

    Attributes
    ----------
    frames : int
        Frames written so far.
    wall_seconds : float
        Wall-clock time spent rendering and encoding, s.

    Examples
    --------
    >>> with MovieWriter("run.mp4", every=200) as movie:     # doctest: +SKIP
    ...     sim.attach(movie)
    ...     sim.run(20.0)
    """

    def __init__(self, path, every: int = 50, fps: float = 25, size_px: int = 600):
        if not (isinstance(every, numbers.Integral) and every >= 1):
            raise InputError(f"every must be an integer >= 1 step, got {every!r}")
        self.every = int(every)
        self.wall_seconds = 0.0
        super().__init__(path, fps, size_px)
        ax = self.figure.add_axes((0.02, 0.02, 0.96, 0.91))
        ax.set_axis_off()
        self._board = BoardArtists(ax)

    def write(self, state) -> None:
        """Render ``state`` and append it as one frame."""
        if self.closed:
            raise InputError(f"MovieWriter for {self.path} is closed")
        start = time.perf_counter()
        self._board.draw(state)
        self.add_frame()
        self.wall_seconds += time.perf_counter() - start

    def __repr__(self) -> str:
        return f"MovieWriter({str(self.path)!r}, every={self.every}, frames={self.frames})"
