"""Figures and movies of a run: thesis Figs 3-8, 3-9, 3-11 and 3-12, and an MP4 of the oxide growing.

Figures are built on matplotlib's object API (no pyplot state) except when a
``draw_*`` function is asked to make its own axes, so that it shows in
notebooks. Files are written atomically (`labrig.files`): a crash never
leaves a half-written PNG or MP4.
"""

from __future__ import annotations

import math
import numbers
from pathlib import Path

import matplotlib
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.cm import ScalarMappable
from matplotlib.colors import LightSource, Normalize
from matplotlib.figure import Figure

from labrig.figures import save_figure  # noqa: F401 (planarize.render.save_figure: its public name)
from labrig.movies import FigureMovie
from labrig.validate import InputError, count, printable

from .anodize import Anodization
from .heightfield import Surface

#: Marker styles of Fig 3-8: metal squares, oxide circles.
METAL = {"marker": "s", "color": "tab:blue"}
OXIDE = {"marker": "o", "color": "tab:red"}
#: Most grid points a slice marks one by one (beyond, its initial surfaces are dashed lines and the final ones solid).
MAX_MARKED_POINTS = 80


def _axes(ax, projection=None, figsize=(6, 4)):
    if ax is not None:
        return ax
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=figsize)
    return fig.add_subplot(projection=projection)


def initial_oxide(run: Anodization) -> Surface:
    """The oxide at the start: the snapshot at 0 nm if there is one, else the initial metal (no oxide yet)."""
    for shot in run.snapshots:
        if shot.target == 0:
            return shot.oxide
    return run.initial


# -- Fig 3-8 -----------------------------------------------------------------------------------

def draw_slice(run: Anodization, ax=None, *, index: int | None = None, axis: int = 0, legend: bool = True):
    """Thesis Fig 3-8: a slice through the surfaces before and after.

    Metal squares, oxide circles; open symbols the initial surfaces, filled
    the final ones (before any oxide the two initial surfaces are one, drawn once with both
    symbols). The key sits under the axes, where it covers no curve.

    Parameters
    ----------
    run : Anodization
    ax : matplotlib.axes.Axes, optional
        Default: a new pyplot figure (so it shows in notebooks).
    index : int, optional
        Grid line of the slice (default: the centre one).
    axis : {0, 1}
        0: heights along x at ``y = y[index]``; 1: along y at ``x = x[index]``.
    legend : bool
        Label the four series.

    Returns
    -------
    matplotlib.axes.Axes
    """
    if axis not in (0, 1):
        raise InputError(f"axis must be 0 (along x) or 1 (along y), got {axis!r}")
    n_across = run.initial.shape[1 - axis]
    index = n_across // 2 if index is None else index
    if not (isinstance(index, numbers.Integral) and 0 <= index < n_across):
        raise InputError(f"index must be a grid line in [0, {n_across - 1}], got {index!r}")
    ax = _axes(ax)
    coord = run.initial.x if axis == 0 else run.initial.y

    def line(surface: Surface) -> np.ndarray:
        return surface.z[:, index] if axis == 0 else surface.z[index, :]

    start = initial_oxide(run)
    same = start.shape == run.initial.shape and np.array_equal(line(start), line(run.initial))
    series = [(run.initial, METAL, "none", "metal and oxide, initial (one surface: no oxide yet)" if same
               else "metal, initial", 7 if same else 5),
              (start, OXIDE, "none", "_nolegend_" if same else "oxide, initial", 4 if same else 5),
              (run.metal, METAL, None, f"metal, after {run.thickness:.3g} nm of oxide", 5),
              (run.oxide, OXIDE, None, f"oxide, after {run.thickness:.3g} nm of oxide", 5)]
    marked = coord.size <= MAX_MARKED_POINTS  # a marker at each grid point only where they can be told apart
    for surface, style, face, label, size in series:
        ax.plot(coord, line(surface), linestyle="-" if marked else ("-" if face is None else "--"),
                linewidth=0.6 if marked else 1.2, markersize=size, color=style["color"],
                marker=style["marker"] if marked else None, markerfacecolor=face if face else style["color"],
                label=label)
    ax.set_xlabel(f"{'x' if axis == 0 else 'y'} (nm)")
    ax.set_ylabel("z (nm)")
    across = run.initial.y[index] if axis == 0 else run.initial.x[index]
    ax.set_title(f"slice at {'y' if axis == 0 else 'x'} = {across:.6g} nm")
    if legend:  # under the axes, where it covers no curve
        ax.legend(fontsize="small", loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=2, frameon=False)
    return ax


# -- Fig 3-9 -----------------------------------------------------------------------------------

def log_axis(ax, values, min_decades: float = 0.5) -> tuple[float, float]:
    """Make ``ax``'s y axis logarithmic, with limits from ``values`` and at least two labelled ticks.

    The limits hold the positive finite ``values`` with a 5 % margin and span at least ``min_decades``
    decades. Over two decades or more the decades are labelled; over fewer, ticks at 1, 2, 5 x 10^k
    (from one decade) or at every digit x 10^k, labelled like 0.05, 2 or 30. Returns the limits.
    """
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    v = np.asarray(values, dtype=float).ravel()
    v = v[np.isfinite(v) & (v > 0)]
    if not v.size:
        raise InputError("a log axis needs data > 0; these are all zero, negative or not finite")
    low, high = math.log10(v.min()), math.log10(v.max())
    margin = max(0.05 * (high - low), 0.5 * (min_decades - (high - low)))
    ax.set_yscale("log")
    ax.set_ylim(10 ** (low - margin), 10 ** (high + margin))
    if high - low + 2 * margin < 2:
        subs = (1.0, 2.0, 5.0) if high - low + 2 * margin >= 1 else tuple(np.arange(1.0, 10.0))
        ax.yaxis.set_major_locator(LogLocator(base=10, subs=subs))
        ax.yaxis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:g}"))
        ax.yaxis.set_minor_formatter(NullFormatter())
    return ax.get_ylim()


def draw_history(run: Anodization, axes=None, *, errorbars: bool = True, log: bool = False):
    """Thesis Figs 3-9 and 3-12: RMS and z-range of metal and oxide against oxide thickness.

    The x axis is the oxide thickness reached (the smallest metal-oxide
    distance); horizontal error bars are the standard deviation of the
    metal-oxide distances (the spread of the oxide's thickness: none on the continuum engine, whose
    oxide is exactly as thick everywhere), vertical ones the continuum engine's estimate of its
    discretization error (`planarize.engines.resolution`).

    Parameters
    ----------
    run : Anodization
    axes : pair of matplotlib.axes.Axes, optional
        Where to draw RMS and z-range. Default: a new pyplot figure with two panels.
    errorbars : bool
        Draw the error bars.
    log : bool
        Logarithmic y axes (Fig 3-12: an exponential decay is a straight line), with limits from the
        data and at least two labelled ticks (`log_axis`); values of 0 are left out. Default: linear from 0.

    Returns
    -------
    (Axes, Axes)
    """
    if axes is None:
        import matplotlib.pyplot as plt

        _, axes = plt.subplots(1, 2, figsize=(10, 4))
    h = run.history
    x = h["thickness_nm"]
    spread = np.asarray(h["distance_std_nm"])
    xerr = spread if errorbars and np.any(spread > 1e-9 * np.max(np.abs(x), initial=1.0)) else None
    for ax, measure, label in zip(axes, ("rms", "zrange"), ("RMS (nm)", "z-range (nm)")):
        for name, style in (("metal", METAL), ("oxide", OXIDE)):
            yerr = h.get(f"{name}_{measure}_error_nm") if errorbars else None
            ax.errorbar(x, h[f"{name}_{measure}_nm"], xerr=xerr, yerr=yerr, color=style["color"], marker=style["marker"],
                        markersize=4, linewidth=1, capsize=2, elinewidth=0.6, label=name)
        ax.set_xlabel("oxide thickness (nm)")
        ax.set_ylabel(label)
        if log:
            log_axis(ax, [h[f"{name}_{measure}_nm"] for name in ("metal", "oxide")])
        else:
            ax.set_ylim(bottom=0)
        ax.legend(fontsize="small")
    return axes


# -- 3-D surfaces (Fig 3-11) -------------------------------------------------------------------

def surface_scale(surfaces) -> float:
    """Half-height of a z window that holds every one of ``surfaces`` around its own mean, nm."""
    half = max(float(np.max(np.abs(s.z - s.z.mean()))) for s in surfaces)
    return half if half > 0 else 1.0


def surface_faces(surface: Surface, max_lines: int = 60):
    """The mesh `draw_surface` draws: grid lines (subsampled to ``max_lines``) and each face's height.

    Returns
    -------
    x, y, z : ndarray, shape (nx, ny)
        Coordinates and heights of the grid points kept, nm (``x`` varies along the first axis).
    faces : ndarray, shape (nx - 1, ny - 1)
        Mean height of each face's four corners, nm, which colours it (coloured by one corner, a
        lone raised point would colour one of its four faces only).
    """
    def lines(n):  # evenly strided, both ends kept (as matplotlib strides)
        stride = max(1, math.ceil(n / max(int(max_lines), 1)))
        return np.unique(np.r_[np.arange(0, n - 1, stride), n - 1])

    rows, cols = lines(surface.shape[0]), lines(surface.shape[1])
    z = surface.z[np.ix_(rows, cols)]
    x, y = np.meshgrid(surface.x[rows], surface.y[cols], indexing="ij")
    faces = 0.25 * (z[:-1, :-1] + z[1:, :-1] + z[:-1, 1:] + z[1:, 1:])
    return x, y, z, faces


#: What the z axis and the colour bar of a 3-D surface show.
HEIGHT_LABEL = "z \u2212 mean (nm)"
#: Grids with at most this many lines per direction are drawn with their mesh lines (the facets show).
MESH_LINES = 24
#: The light of the 3-D surfaces: from the back left, 45 degrees up (a flat face keeps 90 % of its colour).
LIGHT = LightSource(azdeg=315, altdeg=45)


def draw_surface(surface: Surface, ax=None, *, half_range: float | None = None, cmap: str = "viridis",
                 title: str | None = None, max_lines: int = 60, shade: bool = True):
    """A 3-D render of ``surface``'s heights about its own mean, ``z - mean`` (thesis Fig 3-11 style).

    The z axis and the colours show the same quantity, ``z - mean`` in nm, over the same window
    ``[-half_range, half_range]``; the title gives the mean height. Each face is coloured by the mean
    height of its corners and, with ``shade``, lit from one side so that facets of the same height
    stay apart; small grids (up to `MESH_LINES` lines) also show their mesh lines.

    Parameters
    ----------
    surface : Surface
    ax : mpl_toolkits.mplot3d.Axes3D, optional
        Default: a new pyplot figure with 3-D axes.
    half_range : float, optional
        Half-height of the z window and of the colour scale, nm; give the
        same value to every panel of a series so that scales stay fixed while
        the window follows the mean. Default: `surface_scale` of this surface.
    cmap : str
        Colour map of ``z - mean``.
    title : str, optional
        First line of the title (the second gives the mean height).
    max_lines : int
        Most grid lines drawn per direction (larger grids are subsampled for speed).
    shade : bool
        Light the faces (from `LIGHT`); False: flat colours of the height.
    """
    ax = _axes(ax, projection="3d", figsize=(6, 5))
    half = surface_scale([surface]) if half_range is None else float(half_range)
    if not (math.isfinite(half) and half > 0):
        raise InputError(f"half_range must be > 0 nm, got {half_range!r}")
    mean = float(surface.z.mean())
    x, y, z, faces = surface_faces(surface, max_lines)
    colours = np.zeros(z.shape + (4,))  # plot_surface colours the face (i, j) by entry [i, j]
    colours[:-1, :-1] = matplotlib.colormaps[cmap](Normalize(-half, half)(faces - mean))
    mesh = max(z.shape) <= MESH_LINES
    # transposed to matplotlib's layout (y along the rows): the faces' normals then point up (else lit from below)
    ax.plot_surface(x.T, y.T, (z - mean).T, facecolors=colours.transpose(1, 0, 2), rstride=1, cstride=1,
                    linewidth=0.4 if mesh else 0, edgecolor=(0, 0, 0, 0.3) if mesh else None, antialiased=mesh,
                    shade=shade, lightsource=LIGHT)
    ax.set_zlim(-half, half)
    ax.set_xlabel("x (nm)")
    ax.set_ylabel("y (nm)")
    ax.set_zlabel(HEIGHT_LABEL)
    ax.set_title((f"{title}\n" if title else "") + f"mean height {mean:.4g} nm", fontsize="medium")
    return ax


#: Most panels of `snapshots_figure` (each a 3-D surface of 4 x 3.4 in).
MAX_PANELS = 100


def snapshots_figure(run: Anodization, which: str = "oxide", *, cmap: str = "viridis", columns: int = 3) -> Figure:
    """Thesis Fig 3-11: the surfaces at each snapshot, fixed colour and z scale, window shifted with the mean.

    Parameters
    ----------
    run : Anodization
    which : {"oxide", "metal", "both"}
        "both" puts the oxide and metal of each snapshot side by side.
    columns : int
        Panels per row.
    """
    if which not in ("oxide", "metal", "both"):
        raise InputError(f"which must be 'oxide', 'metal' or 'both', got {which!r}")
    kinds = ("oxide", "metal") if which == "both" else (which,)
    panels = [(getattr(shot, kind), thickness_label(kind, shot.thickness)) for shot in run.snapshots for kind in kinds]
    if not panels:
        raise InputError("the run has no snapshots")
    if len(panels) > MAX_PANELS:
        raise InputError(f"the run has {len(run.snapshots):,} snapshots: {len(panels):,} panels, more than the "
                         f"{MAX_PANELS} a figure takes (draw a selection of them)")
    columns = count("columns", columns, 1, MAX_PANELS)
    half = surface_scale([s for s, _ in panels])
    columns = min(len(kinds) * max(1, columns // len(kinds)), len(panels))
    rows = math.ceil(len(panels) / columns)
    spare = rows * columns > len(panels)  # the colour bar goes into the first empty cell, else beside the grid
    width, height = 4.2 * columns + (0.0 if spare else 1.2), 3.6 * rows + 0.7
    fig = Figure(figsize=(width, height))
    FigureCanvasAgg(fig)
    grid = fig.add_gridspec(rows, columns + (0 if spare else 1),
                            width_ratios=[1.0] * columns + ([] if spare else [0.08]))
    for k, (surface, title) in enumerate(panels):
        draw_surface(surface, fig.add_subplot(grid[k // columns, k % columns], projection="3d"),
                     half_range=half, cmap=cmap, title=title)
    if spare:
        cell = fig.add_subplot(grid[len(panels) // columns, len(panels) % columns])
        cell.set_axis_off()
        cax = cell.inset_axes((0.45, 0.1, 0.07, 0.8))
    else:
        cell = fig.add_subplot(grid[:, -1])
        cell.set_axis_off()
        cax = cell.inset_axes((0.0, 0.15, 1.0, 0.7))
    bar = fig.colorbar(ScalarMappable(Normalize(-half, half), cmap), cax=cax)
    bar.set_label(f"{HEIGHT_LABEL}, as the z axes")
    # room, in inches, for the two-line panel titles above and the colour bar's label at the right
    fig.subplots_adjust(left=0.02, right=1.0 - 0.75 / width, top=1.0 - 0.65 / height, bottom=0.1 / height,
                        wspace=0.2, hspace=0.35)
    return fig


# -- figures and files -------------------------------------------------------------------------

def slice_figure(run: Anodization, title: str | None = None) -> Figure:
    """Fig 3-8 as a Figure (no pyplot state)."""
    fig = Figure(figsize=(6.5, 4.8))
    FigureCanvasAgg(fig)
    ax = draw_slice(run, fig.add_subplot())
    if title:  # a scene's name, its control characters escaped (no font has a glyph for them)
        ax.set_title(f"{printable(title)}: {ax.get_title()}")
    fig.tight_layout()
    return fig


def history_figure(run: Anodization, title: str | None = None, *, log: bool = False) -> Figure:
    """Fig 3-9 (``log``: Fig 3-12) as a Figure (no pyplot state); see `draw_history`."""
    fig = Figure(figsize=(10, 4))
    FigureCanvasAgg(fig)
    draw_history(run, fig.subplots(1, 2), log=log)
    if title:
        fig.suptitle(printable(title))
    fig.tight_layout()
    return fig


class SurfaceMovie(FigureMovie):
    """Stream 3-D surface renders to an MP4 (libx264), one frame per `write`.

    Frames share ``half_range`` (nm), so the colour and z scales stay fixed
    while the window follows the mean height. Written to a temporary file and
    renamed onto ``path`` by `close`; an exception in a ``with`` block leaves
    ``path`` untouched.

    Parameters
    ----------
    path : str or Path
        Output file (``.mp4``).
    half_range : float
        Half-height of the z window, nm (> 0).
    fps : float
        Frames per second (> 0).
    size_px : int
        Frame width and height, pixels (even, >= 16).
    """

    half_range: float
    cmap: str

    def __init__(self, path, half_range: float, fps: float = 10, size_px: int = 600, cmap: str = "viridis"):
        if not (isinstance(half_range, numbers.Real) and math.isfinite(half_range) and half_range > 0):
            raise InputError(f"half_range must be > 0 nm, got {half_range!r}")
        self.half_range, self.cmap = float(half_range), cmap
        super().__init__(path, fps, size_px)

    def write(self, surface: Surface, title: str | None = None) -> None:
        """Render ``surface`` and append it as one frame."""
        if self.closed:
            raise InputError(f"SurfaceMovie for {self.path} is closed")
        self.figure.clear()
        ax = self.figure.add_subplot(projection="3d")
        draw_surface(surface, ax, half_range=self.half_range, cmap=self.cmap, title=title)
        bar = self.figure.colorbar(ScalarMappable(Normalize(-self.half_range, self.half_range), self.cmap), ax=ax,
                                   shrink=0.6, pad=0.12)
        bar.set_label(HEIGHT_LABEL)
        self.add_frame()


#: Significant digits of the oxide thickness in panel and frame titles (as in the ``planarize`` summary).
THICKNESS_DIGITS = 4
#: Seconds a movie holds its last frame, the final state, so that every player shows it at the end.
HOLD_S = 1.0


def thickness_label(which: str, thickness: float) -> str:
    """Title of a surface at an oxide ``thickness`` (nm): ``"oxide after 1.001 nm of oxide"``, or
    ``"initial surface (no oxide yet)"`` before any oxide (metal and oxide are then one surface)."""
    if thickness == 0:
        return "initial surface (no oxide yet)"
    return f"{which} after {thickness:.{THICKNESS_DIGITS}g} nm of oxide"


def movie_frames(run: Anodization, which: str = "oxide") -> list[tuple[Surface, float]]:
    """The frames of `save_movie`: ``(surface, thickness in nm)`` of each snapshot, then the final state.

    Each frame is labelled with the thickness its surface was taken at (not the one asked for); the
    last is always the final ``which`` surface at ``run.thickness`` (appended if the snapshots stop short).
    """
    if which not in ("oxide", "metal"):
        raise InputError(f"which must be 'oxide' or 'metal', got {which!r}")
    if not run.snapshots:
        raise InputError("the run has no snapshots to make a movie of")
    frames = [(getattr(shot, which), float(shot.thickness)) for shot in run.snapshots]
    final = getattr(run, which)
    last, reached = frames[-1]
    if not (reached == run.thickness and np.array_equal(last.z, final.z)):
        frames.append((final, run.thickness))
    return frames


def save_movie(run: Anodization, path, which: str = "oxide", fps: float = 10, size_px: int = 600,
               hold_s: float = HOLD_S) -> Path:
    """An MP4 of ``which`` surface ("oxide" or "metal") growing, atomically (frames: `movie_frames`).

    One frame per snapshot, each titled with the thickness of the state it shows; the final state,
    last, is held for ``hold_s`` seconds (at least one frame). Take many snapshots for a smooth
    movie, e.g. ``anodize(..., snapshots=np.linspace(0, t, 51))``.
    """
    frames = movie_frames(run, which)
    if not (isinstance(hold_s, numbers.Real) and 0 <= hold_s <= 60):
        raise InputError(f"hold_s must be in [0, 60] s, got {hold_s!r}")
    with SurfaceMovie(path, surface_scale([surface for surface, _ in frames]), fps=fps, size_px=size_px) as movie:
        for surface, thickness in frames:
            movie.write(surface, thickness_label(which, thickness))
        for _ in range(max(1, round(hold_s * movie.fps)) - 1):
            movie.add_frame()  # the figure still shows the final state
    return Path(path)
