"""Figures and movies of a run: thesis Figs 3-8, 3-9 and 3-11, and an MP4 of the oxide growing.

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
from matplotlib.colors import Normalize
from matplotlib.figure import Figure

from labrig.files import atomic_path
from labrig.movies import FigureMovie
from labrig.validate import InputError

from .anodize import Anodization
from .surface import Surface

#: Marker styles of Fig 3-8: metal squares, oxide circles.
METAL = {"marker": "s", "color": "tab:blue"}
OXIDE = {"marker": "o", "color": "tab:red"}


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
    the final ones.

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

    series = [(run.initial, METAL, "none", "metal, initial"), (initial_oxide(run), OXIDE, "none", "oxide, initial"),
              (run.metal, METAL, None, f"metal, {run.thickness:.3g} nm oxide"),
              (run.oxide, OXIDE, None, f"oxide, {run.thickness:.3g} nm oxide")]
    for surface, style, face, label in series:
        ax.plot(coord, line(surface), linestyle="-", linewidth=0.6, markersize=5, color=style["color"],
                marker=style["marker"], markerfacecolor=face if face else style["color"], label=label)
    ax.set_xlabel(f"{'x' if axis == 0 else 'y'} (nm)")
    ax.set_ylabel("z (nm)")
    across = run.initial.y[index] if axis == 0 else run.initial.x[index]
    ax.set_title(f"slice at {'y' if axis == 0 else 'x'} = {across:.3g} nm")
    if legend:
        ax.legend(fontsize="small")
    return ax


# -- Fig 3-9 -----------------------------------------------------------------------------------

def draw_history(run: Anodization, axes=None, *, errorbars: bool = True):
    """Thesis Fig 3-9: RMS and z-range of metal and oxide against oxide thickness.

    The x axis is the oxide thickness reached (the smallest metal-oxide
    distance); horizontal error bars are the standard deviation of the
    metal-oxide distances (the spread of the oxide's thickness).

    Parameters
    ----------
    run : Anodization
    axes : pair of matplotlib.axes.Axes, optional
        Where to draw RMS and z-range. Default: a new pyplot figure with two panels.

    Returns
    -------
    (Axes, Axes)
    """
    if axes is None:
        import matplotlib.pyplot as plt

        _, axes = plt.subplots(1, 2, figsize=(10, 4))
    h = run.history
    x = h["thickness_nm"]
    xerr = h["distance_std_nm"] if errorbars else None
    for ax, measure, label in zip(axes, ("rms", "zrange"), ("RMS (nm)", "z-range (nm)")):
        for name, style in (("metal", METAL), ("oxide", OXIDE)):
            ax.errorbar(x, h[f"{name}_{measure}_nm"], xerr=xerr, color=style["color"], marker=style["marker"],
                        markersize=4, linewidth=1, capsize=2, elinewidth=0.6, label=name)
        ax.set_xlabel("oxide thickness (nm)")
        ax.set_ylabel(label)
        ax.set_ylim(bottom=0)
        ax.legend(fontsize="small")
    return axes


# -- 3-D surfaces (Fig 3-11) -------------------------------------------------------------------

def surface_scale(surfaces) -> float:
    """Half-height of a z window that holds every one of ``surfaces`` around its own mean, nm."""
    half = max(float(np.max(np.abs(s.z - s.z.mean()))) for s in surfaces)
    return half if half > 0 else 1.0


def draw_surface(surface: Surface, ax=None, *, half_range: float | None = None, cmap: str = "viridis",
                 title: str | None = None, max_lines: int = 60):
    """A 3-D render of ``surface`` in a z window centred on its mean (thesis Fig 3-11 style).

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
    max_lines : int
        Most grid lines drawn per direction (larger grids are subsampled for speed).
    """
    ax = _axes(ax, projection="3d", figsize=(6, 5))
    half = surface_scale([surface]) if half_range is None else float(half_range)
    if not (math.isfinite(half) and half > 0):
        raise InputError(f"half_range must be > 0 nm, got {half_range!r}")
    mean = float(surface.z.mean())
    x, y = np.meshgrid(surface.x, surface.y, indexing="ij")
    face = matplotlib.colormaps[cmap](Normalize(-half, half)(surface.z - mean))
    ax.plot_surface(x, y, surface.z, facecolors=face, rcount=max_lines, ccount=max_lines, linewidth=0,
                    antialiased=False, shade=False)
    ax.set_zlim(mean - half, mean + half)
    ax.set_xlabel("x (nm)")
    ax.set_ylabel("y (nm)")
    ax.set_zlabel("z (nm)")
    if title is not None:
        ax.set_title(title)
    return ax


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
    panels = [(getattr(shot, kind), f"{kind}, {shot.target:.4g} nm oxide") for shot in run.snapshots for kind in kinds]
    if not panels:
        raise InputError("the run has no snapshots")
    half = surface_scale([s for s, _ in panels])
    columns = len(kinds) * max(1, columns // len(kinds))
    rows = math.ceil(len(panels) / columns)
    fig = Figure(figsize=(4 * min(columns, len(panels)), 3.4 * rows))
    FigureCanvasAgg(fig)
    for k, (surface, title) in enumerate(panels):
        draw_surface(surface, fig.add_subplot(rows, min(columns, len(panels)), k + 1, projection="3d"),
                     half_range=half, cmap=cmap, title=title)
    fig.tight_layout()
    return fig


# -- figures and files -------------------------------------------------------------------------

def slice_figure(run: Anodization, title: str | None = None) -> Figure:
    """Fig 3-8 as a Figure (no pyplot state)."""
    fig = Figure(figsize=(6, 4))
    FigureCanvasAgg(fig)
    ax = draw_slice(run, fig.add_subplot())
    if title:
        ax.set_title(f"{title}: {ax.get_title()}")
    fig.tight_layout()
    return fig


def history_figure(run: Anodization, title: str | None = None) -> Figure:
    """Fig 3-9 as a Figure (no pyplot state)."""
    fig = Figure(figsize=(10, 4))
    FigureCanvasAgg(fig)
    draw_history(run, fig.subplots(1, 2))
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig


def save_figure(fig: Figure, path, dpi: int = 100) -> Path:
    """Write ``fig`` to ``path`` (format from the suffix, e.g. PNG), atomically."""
    if not (isinstance(dpi, numbers.Real) and dpi > 0):
        raise InputError(f"dpi must be > 0, got {dpi!r}")
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=dpi)
    return path


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
        draw_surface(surface, self.figure.add_subplot(projection="3d"), half_range=self.half_range,
                     cmap=self.cmap, title=title)
        self.add_frame()


def save_movie(run: Anodization, path, which: str = "oxide", fps: float = 10, size_px: int = 600) -> Path:
    """An MP4 of ``which`` surface ("oxide" or "metal") at each of the run's snapshots, atomically.

    Take many snapshots for a smooth movie, e.g. ``anodize(..., snapshots=np.linspace(0, t, 51))``.
    """
    if which not in ("oxide", "metal"):
        raise InputError(f"which must be 'oxide' or 'metal', got {which!r}")
    if not run.snapshots:
        raise InputError("the run has no snapshots to make a movie of")
    surfaces = [getattr(shot, which) for shot in run.snapshots]
    with SurfaceMovie(path, surface_scale(surfaces), fps=fps, size_px=size_px) as movie:
        for shot, surface in zip(run.snapshots, surfaces):
            movie.write(surface, f"{which}, {shot.thickness:.3g} nm oxide")
    return Path(path)
