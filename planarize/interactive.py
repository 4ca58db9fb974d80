"""Look through a finished anodization run in a notebook: `ThicknessExplorer`.

>>> import planarize
>>> from planarize.interactive import ThicknessExplorer
>>> run = planarize.anodize(planarize.surfaces.hill(), 1.0, snapshots=[0, 0.25, 0.5, 0.75, 1.0])  # doctest: +SKIP
>>> ThicknessExplorer(run)                                                                      # doctest: +SKIP

A slider over the oxide thicknesses at which the run kept both surfaces
(``snapshots=`` of `planarize.anodize`) shows the metal and oxide surfaces in
3-D and along the centre line, next to the run's RMS and z-range curves with a
marker at the selected thickness. Metal and oxide have the colours and markers
of the static figures (`planarize.render`: metal blue squares, oxide red
circles). Needs the ``widgets`` extra (``pip install "nanodisorder[widgets]"``).
"""

from __future__ import annotations

import numpy as np
from matplotlib.lines import Line2D

from labrig.validate import InputError

from .anodize import Anodization
from .metrics import rms, z_range
from .render import METAL, OXIDE


def nearest_snapshot(run: Anodization, thickness: float) -> int:
    """Index of the snapshot of ``run`` whose reached oxide thickness is nearest ``thickness`` (nm).

    Ties go to the thinner one.
    """
    if not run.snapshots:
        raise InputError("the run kept no snapshots: pass snapshots=[...] to planarize.anodize")
    try:
        thickness = float(thickness)
    except (TypeError, ValueError):
        raise InputError(f"thickness must be a number of nm, got {thickness!r}") from None
    if not np.isfinite(thickness):
        raise InputError(f"thickness must be finite, got {thickness!r}")
    return int(np.argmin([abs(s.thickness - thickness) for s in run.snapshots]))


def _labels(run: Anodization) -> list[str]:
    labels = [f"{s.thickness:.4g}" for s in run.snapshots]
    return [f"{label} (#{i})" if labels.count(label) > 1 else label for i, label in enumerate(labels)]


def _marker_path(marker: str):
    """The path of a scatter marker, as ``Axes.scatter`` makes it (for one marker per point)."""
    from matplotlib.markers import MarkerStyle

    style = MarkerStyle(marker)
    return style.get_path().transformed(style.get_transform())


class ThicknessExplorer:
    """Metal and oxide surfaces of a run, one snapshot at a time, chosen by a thickness slider.

    Parameters
    ----------
    run : Anodization
        A finished run with at least one snapshot.
    size : (float, float)
        Figure size, inches (the default, 800 x 560 px, fits a notebook beside JupyterLab's file browser).
    mesh : int
        Most grid lines drawn per side in the 3-D view (>= 2; larger grids are strided).

    Attributes
    ----------
    slider : ipywidgets.SelectionSlider
        Its value is the index of the snapshot shown; its labels are oxide thicknesses, nm.
    figure : matplotlib.figure.Figure
        3-D view (left), centre slice along x (top right), RMS / z-range curves (bottom right), one
        legend for all at the bottom (its ``canvas`` is an ipympl widget).
    ui : ipywidgets.VBox
        The whole widget.
    """

    def __init__(self, run: Anodization, *, size: tuple[float, float] = (8.0, 5.6), mesh: int = 40):
        from labrig.widgets import require_widgets, widget_figure

        w = require_widgets("planarize.interactive")
        if not isinstance(run, Anodization):
            raise TypeError(f"run must be a planarize.Anodization, got {type(run).__name__}")
        if not run.snapshots:
            raise InputError("the run kept no snapshots: pass snapshots=[...] to planarize.anodize")
        if isinstance(mesh, bool) or not isinstance(mesh, int) or mesh < 2:
            raise InputError(f"mesh must be an integer >= 2, got {mesh!r}")
        self.run, self.mesh = run, mesh
        self.figure = widget_figure(size)
        self.slider = w.SelectionSlider(options=list(zip(_labels(run), range(len(run.snapshots)))), value=0,
                                        description="oxide (nm)", continuous_update=True,
                                        layout=w.Layout(width="min(100%, 600px)"))
        self._draw_fixed()
        self.slider.observe(lambda change: self.show(change["new"]), "value")
        self.ui = w.VBox([self.slider, self.figure.canvas])
        self.show(0)  # drawn when the front end shows the canvas (labrig.widgets)

    @property
    def snapshot(self):
        """The snapshot shown."""
        return self.run.snapshots[self.slider.value]

    def select(self, thickness: float):
        """Show the snapshot nearest ``thickness`` (nm); returns it."""
        self.slider.value = nearest_snapshot(self.run, thickness)
        return self.snapshot

    def _draw_fixed(self) -> None:
        """Axes, the initial metal, the history curves and the legend: everything that does not move."""
        fig, run, first = self.figure, self.run, self.run.snapshots[0]
        grid = fig.add_gridspec(2, 2, width_ratios=(1.15, 1), left=0.01, right=0.98, bottom=0.15, top=0.86,
                                wspace=0.28, hspace=0.5)
        self.ax3d = fig.add_subplot(grid[:, 0], projection="3d")
        self.ax_slice = fig.add_subplot(grid[0, 1])
        self.ax_curves = fig.add_subplot(grid[1, 1])
        self.row = first.metal.shape[1] // 2
        x = first.metal.x
        every = max(1, len(x) // 25)  # markers on at most ~25 points of the slice
        ax = self.ax_slice
        ax.plot(x, run.initial.z[:, self.row], color="0.6", ls="--", lw=1, label="initial metal")
        (self.metal_line,) = ax.plot(x, first.metal.z[:, self.row], color=METAL["color"], marker=METAL["marker"],
                                     markersize=3, markevery=every, lw=1.2, label="metal")
        (self.oxide_line,) = ax.plot(x, first.oxide.z[:, self.row], color=OXIDE["color"], marker=OXIDE["marker"],
                                     markersize=3, markevery=every, lw=1.2, label="oxide")
        heights = [run.initial.z] + [z for s in run.snapshots for z in (s.metal.z, s.oxide.z)]
        low, high = min(z.min() for z in heights), max(z.max() for z in heights)
        pad = 0.05 * (high - low or 1.0)
        ax.set_ylim(low - pad, high + pad)
        ax.set_xlabel("x (nm)")
        ax.set_ylabel("z (nm)")
        self.ax3d.set_zlim(low - pad, high + pad)
        self.ax3d.set_xlabel("x (nm)")
        self.ax3d.set_ylabel("y (nm)")
        self.ax3d.set_zlabel("z (nm)")
        ax, h = self.ax_curves, run.history
        for key, style, ls in (("metal_rms_nm", METAL, "-"), ("oxide_rms_nm", OXIDE, "-"),
                               ("metal_zrange_nm", METAL, ":"), ("oxide_zrange_nm", OXIDE, ":")):
            ax.plot(h["thickness_nm"], h[key], color=style["color"], ls=ls, lw=1.2)
        self.marker = ax.axvline(first.thickness, color="k", lw=0.8)
        self.points = ax.scatter(np.zeros(4), np.zeros(4), c=[METAL["color"], OXIDE["color"]] * 2, zorder=3, s=18)
        self.points.set_paths([_marker_path(style["marker"]) for style in (METAL, OXIDE, METAL, OXIDE)])
        ax.set_xlabel("oxide thickness (nm)")
        ax.set_ylabel("nm")
        ax.set_title("RMS (solid), z-range (dotted)", fontsize="medium")
        # one legend in a fixed place: it never moves with the data
        handles = self.ax_slice.get_lines()[:3] + [Line2D([], [], color="k", lw=1.2, ls="-", label="RMS"),
                                                   Line2D([], [], color="k", lw=1.2, ls=":", label="z-range")]
        self.legend = fig.legend(handles=handles, loc="lower center", ncol=5, fontsize="small", frameon=False)
        self._surfaces: list = []

    def show(self, index: int) -> None:
        """Draw snapshot ``index``."""
        shot = self.run.snapshots[index]
        self.metal_line.set_ydata(shot.metal.z[:, self.row])
        self.oxide_line.set_ydata(shot.oxide.z[:, self.row])
        self.ax_slice.set_title(f"centre slice, y = {shot.metal.y[self.row]:.3g} nm", fontsize="medium")
        values = [rms(shot.metal), rms(shot.oxide), z_range(shot.metal), z_range(shot.oxide)]
        self.marker.set_xdata([shot.thickness, shot.thickness])
        self.points.set_offsets(np.column_stack([np.full(4, shot.thickness), values]))
        for artist in self._surfaces:
            artist.remove()
        gx, gy = np.meshgrid(shot.metal.x, shot.metal.y, indexing="ij")
        count = {"rcount": min(self.mesh, gx.shape[0]), "ccount": min(self.mesh, gx.shape[1])}
        self._surfaces = [self.ax3d.plot_surface(gx, gy, shot.metal.z, color=METAL["color"], alpha=0.9, **count),
                          self.ax3d.plot_surface(gx, gy, shot.oxide.z, color=OXIDE["color"], alpha=0.45, **count)]
        d = shot.distances
        self.figure.suptitle(f"oxide {shot.thickness:.4g} nm (asked {shot.target:.4g} nm)\nmetal-oxide distance "
                             f"{d.mean():.4g} ± {d.std():.2g} nm (mean ± std over the grid)", fontsize="medium")
        self.figure.canvas.draw_idle()

    def _repr_mimebundle_(self, **kwargs):
        return self.ui._repr_mimebundle_(**kwargs)
