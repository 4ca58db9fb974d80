"""Pictures and movies of a board: dots coloured by size (viridis, with a colour bar), heavy dots, PNG, MP4.

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

import matplotlib
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.cm import ScalarMappable
from matplotlib.collections import EllipseCollection, LineCollection
from matplotlib.colorbar import Colorbar
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Rectangle
from matplotlib.text import Text

from labrig.figures import save_figure
from labrig.movies import FigureMovie
from labrig.validate import InputError

#: Colour map of the dots' sizes: perceptually uniform, and readable with the common colour-vision deficiencies.
SIZE_CMAP = "viridis"
#: Half-width of the colour scale about the diameter when every dot is one size (a fraction of the diameter).
EQUAL_SPAN = 0.05


def size_range(radii) -> tuple[float, float]:
    """The diameters, px, at the first and the last colour of `SIZE_CMAP`: the smallest dot's and the largest's
    (+- `EQUAL_SPAN` of the diameter when all are one size, which then take the middle colour)."""
    d = 2.0 * np.asarray(radii, dtype=float).reshape(-1)
    d = d[np.isfinite(d)]
    if not d.size:
        return 1.0 - EQUAL_SPAN, 1.0 + EQUAL_SPAN
    low, high = float(d.min()), float(d.max())
    if not high - low > 1e-9 * abs(high):
        mean = float(d.mean())
        low, high = mean * (1.0 - EQUAL_SPAN), mean * (1.0 + EQUAL_SPAN)
    return low, high


#: Robust deviations either side of the median diameter that `robust_size_range` spans.
ROBUST_SPAN = 3.0


def robust_size_range(radii) -> tuple[float, float]:
    """The diameters, px, at the first and the last colour when a few outliers must not stretch the scale (measured
    films): the median +- `ROBUST_SPAN` robust deviations (1.4826 x the median absolute deviation), within the
    smallest and the largest diameter; `size_range` when the deviation is 0."""
    d = 2.0 * np.asarray(radii, dtype=float).reshape(-1)
    d = d[np.isfinite(d)]
    if d.size < 3:
        return size_range(radii)
    median = float(np.median(d))
    deviation = 1.4826 * float(np.median(np.abs(d - median)))
    low, high = max(float(d.min()), median - ROBUST_SPAN * deviation), min(float(d.max()), median + ROBUST_SPAN * deviation)
    return (low, high) if high - low > 1e-9 * abs(high) else size_range(radii)


def _checked_range(diameters) -> tuple[float, float]:
    low, high = (float(v) for v in diameters)
    if not (math.isfinite(low) and math.isfinite(high) and 0 <= low < high):
        raise InputError(f"diameters must be (low, high) with 0 <= low < high px, got {tuple(diameters)!r}")
    return low, high


def size_colours(radii, diameters: tuple[float, float] | None = None) -> np.ndarray:
    """RGB colour of each dot by its diameter: `SIZE_CMAP` (viridis: small dark blue-violet, large yellow).

    Parameters
    ----------
    radii : array_like, shape (N,)
        Dot radii, px.
    diameters : (float, float), optional
        The diameters, px, at the first and the last colour (smaller and larger dots take those).
        Default: `size_range` of ``radii``.

    Returns
    -------
    ndarray, shape (N, 3)
        RGB in [0, 1]. With equal sizes every dot takes the middle colour.
    """
    low, high = size_range(radii) if diameters is None else _checked_range(diameters)
    d = 2.0 * np.asarray(radii, dtype=float).reshape(-1)
    return matplotlib.colormaps[SIZE_CMAP](Normalize(low, high, clip=True)(d))[:, :3]


#: Relative margin of `heavy_dots`: the boards' mean diameter stands in for the scene's nominal one,
#: which differs by a few per cent on small boards.
HEAVY_MARGIN = 0.05
#: Edges of the dots: (colour, line width in points) of an ordinary and of a heavy dot.
DOT_EDGE = ((0.0, 0.0, 0.0, 0.5), 0.3)
HEAVY_EDGE = ((0.0, 0.0, 0.0, 1.0), 1.8)


def heavy_dots(masses, radii) -> np.ndarray:
    """Which dots are heavier than their size makes them: the heavy half of a bimodal board.

    A dot is heavy when its mass exceeds both the mean dot mass (1) and the mass a dot of its size
    has under the steepest size-based mass model, ``(d / mean d)^3`` (``mass_model = "volume"``),
    by more than `HEAVY_MARGIN` (5 %; mean d is the board's), and also exceeds by that margin the
    board's own volume law, ``c d^3`` with ``c`` the lower quartile of the dots' mass per ``d^3`` (so a
    small board whose mean diameter is a few per cent off the nominal one of its masses has no heavy
    dot: the heavy half of a bimodal board never reaches that quartile). So no dot of the ``"equal"``,
    ``"area"`` or ``"volume"`` models is heavy, and under ``"bimodal"`` (thesis Fig 2-6b,
    Table 2.1) the heavy dots are those given ``heavy_mass``, except a heavy dot so large that its
    size alone would make it as heavy (``1.05 (d / mean d)^3 >= heavy_mass``).

    Parameters
    ----------
    masses : array_like, shape (N,) or None
        Dot masses in units of the mean dot mass; None: every dot is of mean mass.
    radii : array_like, shape (N,)
        Dot radii, px.

    Returns
    -------
    ndarray of bool, shape (N,)
    """
    r = np.asarray(radii, dtype=float).reshape(-1)
    if masses is None or r.size == 0:
        return np.zeros(r.size, dtype=bool)
    m = np.asarray(masses, dtype=float).reshape(-1)
    if m.size != r.size:
        raise InputError(f"masses and radii must have the same length, got {m.size} and {r.size}")
    by_size = np.maximum(1.0, (r / r.mean()) ** 3)
    # and heavier than the board's own volume law: the lightest quarter's mass per r^3 (a board whose masses
    # follow d^3 about a nominal diameter a few per cent off its mean has no heavy dot)
    law = np.quantile(m / r**3, 0.25) * r**3
    return (m > by_size * (1.0 + HEAVY_MARGIN)) & (m > law * (1.0 + HEAVY_MARGIN))


def _edges(state, n: int):
    """Edge colours (N, 4) and line widths (N,) of the dots: dark and thick for heavy ones."""
    heavy = heavy_dots(getattr(state, "masses", None), state.radii)
    colours = np.where(heavy[:, None], HEAVY_EDGE[0], DOT_EDGE[0])
    widths = np.where(heavy, HEAVY_EDGE[1], DOT_EDGE[1])
    return colours, widths


def key_label(state, unit: str = "px") -> str:
    """What the size colour bar says: the diameter, the board's mean and SD, and the heavy dots when there are.

    ``unit`` names the length unit of the board's coordinates (px, or nm for a board drawn to scale).
    """
    d = 2.0 * np.asarray(state.radii, dtype=float).reshape(-1)
    label = f"dot diameter d ({unit})"
    if d.size:
        label += f": mean {d.mean():.3g}, SD {d.std():.2g}" + (" (all one size)" if d.std() <= 1e-9 * d.mean() else "")
    heavy = heavy_dots(getattr(state, "masses", None), state.radii)
    if heavy.any():
        label += f"\nthick dark edge: heavy, heavier than its size makes it ({int(heavy.sum())} of {heavy.size} dots)"
    return label


def add_key(ax, state, unit: str = "px", *, diameters: tuple[float, float] | None = None, cax=None) -> Colorbar:
    """The key of the size colours: a horizontal colour bar labelled with `key_label`; returns the Colorbar.

    Drawn in ``cax`` if given, else under ``ax`` (space taken from it). ``diameters`` as in `size_colours`.
    """
    low, high = size_range(state.radii) if diameters is None else _checked_range(diameters)
    mappable = ScalarMappable(Normalize(low, high), SIZE_CMAP)
    d = 2.0 * np.asarray(state.radii, dtype=float)
    d = d[np.isfinite(d)]
    below, above = bool(d.size and d.min() < low * (1 - 1e-9)), bool(d.size and d.max() > high * (1 + 1e-9))
    extend = ("both" if above else "min") if below else ("max" if above else "neither")  # arrows: dots beyond it
    fig = ax.figure
    if cax is None:
        bar = fig.colorbar(mappable, ax=ax, location="bottom", shrink=0.7, fraction=0.04, pad=0.1, extend=extend)
    else:
        bar = fig.colorbar(mappable, cax=cax, orientation="horizontal", extend=extend)
    bar.set_label(key_label(state, unit), fontsize="small")
    bar.ax.tick_params(labelsize="small")
    return bar


class BoardArtists:
    """The artists of one board on one Axes, created once and then updated."""

    def __init__(self, ax):
        self.ax = ax
        self.dots = self.walls = self.outline = None

    def draw(self, state, colours=None, show_time: bool = True, title: str = "",
             colour_range: tuple[float, float] | None = None) -> None:
        """Draw ``state`` (the first call) or move the artists to it; the axes' title is ``title`` and, with
        ``show_time``, the board's time. ``colours`` default to `size_colours` over ``colour_range`` (px)."""
        ax = self.ax
        w, h = (float(v) for v in state.box)
        positions = np.asarray(state.positions, dtype=float).reshape(-1, 2)
        diameters = 2.0 * np.asarray(state.radii, dtype=float)
        walls = np.asarray(getattr(state, "walls", np.zeros((0, 4))), dtype=float).reshape(-1, 2, 2)
        if colours is None:
            colours = size_colours(state.radii, colour_range)
        edges, widths = _edges(state, len(diameters))
        if self.dots is None:
            self.outline = Rectangle((0, 0), w, h, fill=False, edgecolor="0.6", linewidth=0.8,
                                     linestyle="--", zorder=1)
            ax.add_patch(self.outline)
            self.walls = LineCollection(walls,  # type: ignore[arg-type]  # the stub wants a Sequence; arrays work too
                                        colors="black", linewidths=1.5, zorder=3)
            ax.add_collection(self.walls, autolim=False)
            self.dots = EllipseCollection(
                diameters, diameters, np.zeros(len(diameters)), units="xy", offsets=positions,
                offset_transform=ax.transData, facecolors=colours, edgecolors=edges,
                linewidths=widths, zorder=2,
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
            self.dots.set_edgecolor(edges)
            self.dots.set_linewidth(widths)
        pad = 0.01 * max(w, h)
        ax.set_xlim(-pad, w + pad)
        ax.set_ylim(-pad, h + pad)
        when = f"t = {float(getattr(state, 'time', 0.0)):.1f} s" if show_time else ""
        ax.set_title(", ".join(part for part in (title, when) if part), fontsize="medium")


def draw_state(state, ax=None, colours=None, show_time: bool = True, key: bool = False, title: str = ""):
    """Draw a board: outline, walls (black), dots coloured by size, heavy dots with a dark edge; axes in px.

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
    key : bool
        Add the colour bar of the size colours (and the heavy dots) below the axes (`add_key`); only
        meaningful with the default size colours.
    title : str
        What the axes' title says before the time (the run's name and parameters, say).

    Returns
    -------
    matplotlib.axes.Axes
        The axes drawn on, in px with equal aspect and y up.
    """
    if ax is None:
        import matplotlib.pyplot as plt

        _, ax = plt.subplots(figsize=(6, 6))
    BoardArtists(ax).draw(state, colours, show_time, title)
    ax.set_xlabel("x (px)")
    ax.set_ylabel("y (px)")
    if key:
        add_key(ax, state)
    return ax


def nice_length(limit: float) -> float:
    """The largest 1, 2 or 5 times a power of ten that is at most ``limit`` (> 0): a scale bar's length."""
    power = 10.0 ** math.floor(math.log10(limit))
    return max(k * power for k in (1.0, 2.0, 5.0) if k * power <= limit)


#: A still picture zooms to the occupied region when that is less than this share of the board.
ZOOM_BELOW = 0.5


def occupied_region(state) -> tuple[float, float, float, float]:
    """``(x0, y0, x1, y1)``, px: the dots and the walls inside the board, one mean diameter around them,
    within the board (the whole board when it holds neither)."""
    w, h = (float(v) for v in state.box)
    positions = np.asarray(state.positions, dtype=float).reshape(-1, 2)
    radii = np.asarray(state.radii, dtype=float).reshape(-1)
    walls = np.asarray(getattr(state, "walls", np.zeros((0, 4))), dtype=float).reshape(-1, 4)
    on_edge = (((walls[:, 0] == walls[:, 2]) & np.isin(walls[:, 0], (0.0, w)))
               | ((walls[:, 1] == walls[:, 3]) & np.isin(walls[:, 1], (0.0, h))))
    inner = walls[~on_edge].reshape(-1, 2)
    low = np.concatenate([positions - radii[:, None], inner])
    high = np.concatenate([positions + radii[:, None], inner])
    if low.size == 0:
        return 0.0, 0.0, w, h
    pad = 2.0 * float(radii.mean()) if radii.size else 0.02 * max(w, h)
    x0, y0 = np.maximum(low.min(axis=0) - pad, 0.0)
    x1, y1 = np.minimum(high.max(axis=0) + pad, (w, h))
    return float(x0), float(y0), float(x1), float(y1)


def save_png(state, path, dpi: int = 100, title: str = "", colour_range: tuple[float, float] | None = None) -> Path:
    """Write a picture of the board to ``path`` (PNG at ``dpi``, at most `labrig.figures.MAX_DPI`), atomically.

    Axes in px, titled ``title`` (the run's name and parameters, say) and the board's time, with the colour
    bar of the sizes (and the heavy dots) below the board, over ``colour_range`` (px; default `size_range`).
    A board whose dots and inner walls fill less than `ZOOM_BELOW` of it (a grating channel, a small deposit)
    is shown zoomed to them (`occupied_region`; the title says so): 6 in wide, or 10 in for a flat region.

    Returns
    -------
    pathlib.Path
        The path written.
    """
    w, h = (float(v) for v in state.box)
    x0, y0, x1, y1 = occupied_region(state)
    zoom = (x1 - x0) * (y1 - y0) < ZOOM_BELOW * w * h and x1 > x0 and y1 > y0
    if not zoom:
        x0, y0, x1, y1 = 0.0, 0.0, w, h
    aspect = (y1 - y0) / max(x1 - x0, 1e-12)
    # inches: the key (colour bar and its label) and the x axis under the board, the title above it
    below, above = 1.45, 0.75 if title else 0.45
    if aspect >= 0.6:
        width, board_in = 6.0, 4.5
    else:  # a flat region: 10 in wide, as tall as it needs
        width, board_in = 10.0, 10.0 * 0.76 * aspect
    height = below + board_in + above
    fig = Figure(figsize=(width, height))
    FigureCanvasAgg(fig)
    ax = fig.add_axes((0.14, below / height, 0.76, board_in / height))
    cax = fig.add_axes((0.14 + 0.76 * 0.15, 0.62 / height, 0.76 * 0.7, 0.14 / height))
    BoardArtists(ax).draw(state, title=title, colour_range=colour_range)
    ax.set_xlabel("x (px)")
    ax.set_ylabel("y (px)")
    add_key(ax, state, diameters=colour_range, cax=cax)
    if zoom:
        ax.set_xlim(x0, x1)
        ax.set_ylim(y0, y1)
        ax.set_title(f"{ax.get_title()}\n(zoomed to the dots and walls: x {x0:.0f}-{x1:.0f}, y {y0:.0f}-{y1:.0f} "
                     f"of a {w:.0f} x {h:.0f} px board)", fontsize="small")
    return save_figure(fig, path, dpi, format="png")


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
    title : str
        What each frame's title says before the time (the run's name and parameters, say).
    diameters : (float, float), optional
        The diameters, px, at the first and the last colour of every frame (a deposition's range, so that a
        dot keeps its colour as others arrive). Default: each frame's own (`size_range`).

    Attributes
    ----------
    frames : int
        Frames written so far.
    wall_seconds : float
        Wall-clock time spent rendering and encoding, s.

    Examples
    --------
    Two dots jiggling for half a second (25 steps of 20 ms), a frame every 5 steps:

    >>> import qdots
    >>> scene = qdots.Scene(box=(100, 100), positions=[[30, 50], [70, 50]], radii=[7.5, 7.5])
    >>> sim = qdots.Simulation(scene, [qdots.ThermalKicks()], seed=1)
    >>> with MovieWriter("run.mp4", every=5) as movie:
    ...     _ = sim.attach(movie)
    ...     _ = sim.run(0.5)
    >>> movie.frames
    6
    """

    #: Most frames a movie takes (over an hour at 25 frames/s; matplotlib draws each in ~20 ms): a run that
    #: would give it more is refused before it starts (`qdots.writers`).
    max_records = 100_000

    def __init__(self, path, every: int = 50, fps: float = 25, size_px: int = 600, title: str = "",
                 diameters: tuple[float, float] | None = None):
        if not (isinstance(every, (int, numbers.Integral)) and every >= 1):  # int: so that mypy sees an int pass
            raise InputError(f"every must be an integer >= 1 step, got {every!r}")
        self.every = int(every)
        self.wall_seconds = 0.0
        self.title = str(title)
        self.diameters = None if diameters is None else _checked_range(diameters)
        super().__init__(path, fps, size_px)
        ax = self.figure.add_axes((0.02, 0.15, 0.96, 0.72 if self.title else 0.78))
        ax.set_axis_off()
        self._board = BoardArtists(ax)
        self._bar: Line2D | None = None
        self._bar_label: Text | None = None
        self._key: Colorbar | None = None

    def _legend(self, state) -> None:
        """Under the board: a scale bar of a round length in px (and in mean diameters), and the colour bar of
        the sizes (over `diameters`, else over this frame's dots)."""
        fig, ax = self.figure, self._board.ax
        w = float(state.box[0])
        length = nice_length(0.25 * w)
        x0, x1 = (ax.transData + fig.transFigure.inverted()).transform([(0.0, 0.0), (length, 0.0)])[:, 0]
        d = 2.0 * np.asarray(state.radii, dtype=float)
        m = float(d.mean()) if d.size else 0.0
        size = f" = {length / m:.3g} mean diameters" if m > 0 else ""
        if self._bar is None:
            self._bar = Line2D([x0, x1], [0.05, 0.05], transform=fig.transFigure, color="black", linewidth=3)
            fig.add_artist(self._bar)
            self._bar_label = fig.text(x0, 0.065, "", fontsize="small", va="bottom")
            self._key = add_key(ax, state, diameters=self.diameters, cax=fig.add_axes((0.5, 0.065, 0.46, 0.022)))
        elif self.diameters is None:
            assert self._key is not None  # made with the bar, on the first frame
            self._key.mappable.set_norm(Normalize(*size_range(state.radii)))
        assert self._bar_label is not None and self._key is not None  # made with the bar, on the first frame
        self._key.set_label(key_label(state).replace("\nthick", "; thick"), fontsize="x-small")
        self._bar.set_xdata([x0, x1])
        self._bar_label.set_text(f"{length:g} px{size}")

    def write(self, state) -> None:
        """Render ``state`` (with a scale bar and the size key under it) and append it as one frame."""
        if self.closed:
            raise InputError(f"MovieWriter for {self.path} is closed")
        start = time.perf_counter()
        self._board.draw(state, title=self.title, colour_range=self.diameters)
        self._legend(state)
        self.add_frame()
        self.wall_seconds += time.perf_counter() - start

    def __repr__(self) -> str:
        return f"MovieWriter({str(self.path)!r}, every={self.every}, frames={self.frames})"
