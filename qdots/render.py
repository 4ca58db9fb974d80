"""Pictures and movies of a board: size colouring (thesis Fig 2-2), heavy dots, a key, PNG, MP4.

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
from matplotlib.lines import Line2D
from matplotlib.patches import Rectangle
from matplotlib.transforms import ScaledTranslation

from labrig.figures import save_figure
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


def key_entries(state, unit: str = "px") -> tuple[list, list[str], str]:
    """The key of a board's size colours (and heavy dots): legend handles, labels and a title.

    The colours follow `size_colours` with its defaults: ``m`` the mean diameter and ``s`` the
    standard deviation of the diameters, px. A dot is fully red at ``d >= m + s``, fully blue at
    ``d <= m - s`` and pure green at ``d = m``; sizes in between mix. Heavy dots (`heavy_dots`)
    have a thick dark edge.

    ``unit`` names the length unit of the board's coordinates (px, or nm for a board drawn to scale).

    Returns
    -------
    handles : list of matplotlib.lines.Line2D
    labels : list of str
    title : str
    """
    d = 2.0 * np.asarray(state.radii, dtype=float).reshape(-1)
    m = float(d.mean()) if d.size else 0.0
    s = float(d.std()) if d.size else 0.0

    def dot(colour, edge=DOT_EDGE):
        return Line2D([], [], linestyle="none", marker="o", markersize=9, markerfacecolor=colour,
                      markeredgecolor=edge[0], markeredgewidth=max(edge[1], 0.6))

    if d.size and s > 1e-12 * m:
        handles = [dot((1.0, 0.0, 0.0)), dot((0.0, 1.0, 0.0)), dot((0.0, 0.0, 1.0))]
        labels = [f"red: large, d \u2265 m + s = {m + s:.3g} {unit}", f"green: mean size, d = m = {m:.3g} {unit}",
                  f"blue: small, d \u2264 m \u2212 s = {m - s:.3g} {unit}"]
        title = f"colour by diameter d (mean m, std s = {s:.2g} {unit}; mixed in between)"
    else:
        handles, labels = [dot((0.0, 1.0, 0.0))], [f"green: all one size, d = {m:.3g} {unit}"]
        title = "colour by diameter d"
    heavy = heavy_dots(getattr(state, "masses", None), state.radii)
    if heavy.any():
        handles.append(dot((0.0, 1.0, 0.0), HEAVY_EDGE))
        labels.append(f"dark edge: heavy, heavier than its size makes it ({int(heavy.sum())} of {heavy.size})")
    return handles, labels, title


def add_key(ax, state, unit: str = "px", **legend):
    """Put the key of `key_entries` on ``ax`` (under its x label by default); returns the Legend.

    ``unit`` names the length unit of the board's coordinates; ``legend`` overrides
    `matplotlib.axes.Axes.legend` arguments (``loc``, ``bbox_to_anchor``, ...).
    """
    handles, labels, title = key_entries(state, unit)
    below = ax.transAxes + ScaledTranslation(0.0, -0.5, ax.figure.dpi_scale_trans)  # 0.5 in: under the x label
    options = {"loc": "upper center", "bbox_to_anchor": (0.5, 0.0), "bbox_transform": below, "ncol": 1,
               "fontsize": "small", "title_fontsize": "small", "frameon": False, "handletextpad": 0.3,
               "labelspacing": 0.3}
    return ax.legend(handles, labels, title=title, **{**options, **legend})


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
        edges, widths = _edges(state, len(diameters))
        if self.dots is None:
            self.outline = Rectangle((0, 0), w, h, fill=False, edgecolor="0.6", linewidth=0.8,
                                     linestyle="--", zorder=1)
            ax.add_patch(self.outline)
            self.walls = LineCollection(walls, colors="black", linewidths=1.5, zorder=3)
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
        ax.set_title(f"t = {float(getattr(state, 'time', 0.0)):.1f} s" if show_time else "")


def draw_state(state, ax=None, colours=None, show_time: bool = True, key: bool = False):
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
        Add the key of the size colours and heavy dots below the axes (`add_key`); only
        meaningful with the default size colours.

    Returns
    -------
    matplotlib.axes.Axes
        The axes drawn on, in px with equal aspect and y up.
    """
    if ax is None:
        import matplotlib.pyplot as plt

        _, ax = plt.subplots(figsize=(6, 6))
    BoardArtists(ax).draw(state, colours, show_time)
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


def save_png(state, path, dpi: int = 100) -> Path:
    """Write a picture of the board to ``path`` (PNG at ``dpi``, at most `labrig.figures.MAX_DPI`), atomically.

    Axes in px, with the key of the size colours and of the heavy dots below the board. A board whose
    dots and inner walls fill less than `ZOOM_BELOW` of it (a grating channel, a small deposit) is shown
    zoomed to them (`occupied_region`; the title says so): on 6 x 6 in, or 10 in wide for a flat region.

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
    if aspect >= 0.6:
        fig = Figure(figsize=(6, 6))
        FigureCanvasAgg(fig)
        ax = fig.add_axes((0.14, 0.27, 0.76, 0.66))
    else:  # a flat region: 10 in wide, as tall as it needs
        board_in = 10.0 * 0.76 * aspect
        fig = Figure(figsize=(10.0, board_in + 2.3))
        FigureCanvasAgg(fig)
        ax = fig.add_axes((0.14, 1.75 / (board_in + 2.3), 0.76, board_in / (board_in + 2.3)))
    draw_state(state, ax, key=True)
    if zoom:
        ax.set_xlim(x0, x1)
        ax.set_ylim(y0, y1)
        ax.set_title(f"{ax.get_title()}  (zoomed to the dots and walls: x {x0:.0f}-{x1:.0f}, y {y0:.0f}-{y1:.0f} "
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

    #: Most frames a movie takes (over an hour at 25 frames/s; matplotlib draws each in ~20 ms): a run that
    #: would give it more is refused before it starts (`qdots.writers`).
    max_records = 100_000

    def __init__(self, path, every: int = 50, fps: float = 25, size_px: int = 600):
        if not (isinstance(every, numbers.Integral) and every >= 1):
            raise InputError(f"every must be an integer >= 1 step, got {every!r}")
        self.every = int(every)
        self.wall_seconds = 0.0
        super().__init__(path, fps, size_px)
        ax = self.figure.add_axes((0.02, 0.1, 0.96, 0.84))
        ax.set_axis_off()
        self._board = BoardArtists(ax)
        self._bar = self._bar_label = self._key = None

    def _legend(self, state) -> None:
        """Under the board: a scale bar of a round length in px (and in mean diameters) and the size key."""
        fig, ax = self.figure, self._board.ax
        w = float(state.box[0])
        length = nice_length(0.25 * w)
        x0, x1 = (ax.transData + fig.transFigure.inverted()).transform([(0.0, 0.0), (length, 0.0)])[:, 0]
        d = 2.0 * np.asarray(state.radii, dtype=float)
        m, sd = (float(d.mean()), float(d.std())) if d.size else (0.0, 0.0)
        size = f" = {length / m:.3g} mean diameters" if m > 0 else ""
        if sd > 1e-12 * m:
            key = f"red: d \u2265 {m + sd:.3g} px, green: {m:.3g} px, blue: \u2264 {m - sd:.3g} px"
        else:
            key = f"green: all {m:.3g} px" if m > 0 else ""
        if heavy_dots(getattr(state, "masses", None), state.radii).any():
            key += "; dark edge: heavy"
        if self._bar is None:
            self._bar = Line2D([x0, x1], [0.05, 0.05], transform=fig.transFigure, color="black", linewidth=3)
            fig.add_artist(self._bar)
            self._bar_label = fig.text(x0, 0.065, "", fontsize="small", va="bottom")
            self._key = fig.text(0.98, 0.03, "", fontsize="small", ha="right", va="bottom")
        self._bar.set_xdata([x0, x1])
        self._bar_label.set_text(f"{length:g} px{size}")
        self._key.set_text(key)

    def write(self, state) -> None:
        """Render ``state`` (with a scale bar and the size key under it) and append it as one frame."""
        if self.closed:
            raise InputError(f"MovieWriter for {self.path} is closed")
        start = time.perf_counter()
        self._board.draw(state)
        self._legend(state)
        self.add_frame()
        self.wall_seconds += time.perf_counter() - start

    def __repr__(self) -> str:
        return f"MovieWriter({str(self.path)!r}, every={self.every}, frames={self.frames})"
