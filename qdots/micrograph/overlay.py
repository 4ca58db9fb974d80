"""The pictures of a measured film: the detections drawn on the image, and the image beside its simulation.

`overlay_figure` draws what `qdots.micrograph.measure.measure_image` found on the image (circles coloured
by size on viridis with a labelled colour bar, cut dots dashed, what was left out hatched, the scale bar
outlined, a scale bar in nm); `save_overlay` writes it atomically. The image beside a simulated film is
`qdots.inference.plots.side_by_side_figure`.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import PatchCollection
from matplotlib.figure import Figure
from matplotlib.patches import Circle, Rectangle

from labrig.figures import save_figure
from labrig.lazy import moved_names

from ..render import add_key, nice_length, robust_size_range, size_colours
from .film import film_state
from .measure import MeasuredFilm


def draw_scale_bar(ax, nm_per_px: float | None, width_px: float, height_px: float, y_down: bool = True) -> None:
    """A white-on-black scale bar of a round length (about a fifth of the width) in the lower left corner."""

    if nm_per_px is None or not math.isfinite(nm_per_px):
        return
    length_nm = nice_length(0.2 * width_px * nm_per_px)
    length = length_nm / nm_per_px
    x = 0.04 * width_px
    thick = max(2.0, 0.012 * height_px)
    y = height_px - 0.05 * height_px if y_down else 0.05 * height_px
    ax.add_patch(Rectangle((x - 0.01 * width_px, y - 3.5 * thick if y_down else y - thick),
                           length + 0.02 * width_px, 4.5 * thick, color="black", alpha=0.6, lw=0))
    ax.add_patch(Rectangle((x, y - thick if y_down else y), length, thick, color="white", lw=0))
    label = f"{length_nm:g} nm" if length_nm < 1000 else f"{length_nm / 1000:g} µm"
    ax.text(x + 0.5 * length, y - 1.4 * thick if y_down else y + 1.6 * thick, label, color="white",
            ha="center", va="bottom", fontsize="small")


def overlay_range(film: MeasuredFilm) -> tuple[float, float]:
    """The diameters, image px, at the ends of an overlay's colour scale: `qdots.render.robust_size_range` of the
    whole dots that are not stacked (a few false or merged detections do not stretch it)."""
    det = film.detection
    stacked = film.stacked if film.stacked is not None else np.zeros(det.n_dots, dtype=bool)
    return robust_size_range(0.5 * det.diameters[~det.cut & ~stacked])


def save_overlay_axes(film: MeasuredFilm, ax, extent_nm: tuple[float, float] | None = None,
                      diameters: tuple[float, float] | None = None) -> None:
    """Draw the image and its detections on ``ax``: circles coloured by size (`qdots.render.size_colours`),
    dashed white for dots cut by the edge, dotted red for dots stacked on a neighbour (left out of the sizes),
    centres as yellow crosses, a scale bar. With ``extent_nm`` the axes run in nm (row 0 at the top), else in image
    px. The colours span ``diameters`` (image px; default `overlay_range`)."""

    h, w = film.image.shape
    det = film.detection
    k = 1.0 if extent_nm is None else extent_nm[0] / w
    ax.imshow(film.image.pixels, cmap="gray", extent=(0, w * k, h * k, 0), interpolation="nearest")
    stacked = film.stacked if film.stacked is not None else np.zeros(det.n_dots, dtype=bool)
    whole = ~det.cut & ~stacked
    span = overlay_range(film) if diameters is None else diameters
    colours = size_colours(0.5 * det.diameters[whole], span) if whole.any() else np.zeros((0, 3))
    ax.add_collection(PatchCollection([Circle(c * k, 0.5 * d * k) for c, d in zip(det.centres[whole],
                                                                                 det.diameters[whole])],
                                      facecolor="none", edgecolor=colours, linewidth=1.2))
    ax.add_collection(PatchCollection([Circle(c * k, 0.5 * d * k) for c, d in zip(det.centres[det.cut],
                                                                                 det.diameters[det.cut])],
                                      facecolor="none", edgecolor="white", linewidth=0.9, linestyle="--"))
    ax.add_collection(PatchCollection([Circle(c * k, 0.5 * d * k) for c, d in zip(det.centres[stacked & ~det.cut],
                                                                                 det.diameters[stacked & ~det.cut])],
                                      facecolor="none", edgecolor="red", linewidth=0.9, linestyle=":"))
    ax.plot(det.centres[:, 0] * k, det.centres[:, 1] * k, "+", color="yellow", markersize=3, markeredgewidth=0.6)
    mark_annotations(ax, film, k)
    draw_scale_bar(ax, film.nm_per_px / k if film.nm_per_px is not None else None, w * k, h * k)
    ax.set_xlim(0, w * k)
    ax.set_ylim(h * k, 0)


def mark_annotations(ax, film: MeasuredFilm, k: float = 1.0) -> None:
    """Shade what was left out (strips, label boxes) and outline the scale bar, with its length in px and, when
    it gave the scale, in nm (``k``: axes units per image px)."""

    found = film.annotations
    if found is None:
        return
    h, w = film.image.shape
    x0, y0, x1, y1 = found.window
    shaded = [(0, 0, w, y0), (0, y1, w, h), (0, y0, x0, y1), (x1, y0, w, y1), *found.boxes]
    for a, b, c, d in shaded:
        if c > a and d > b:
            ax.add_patch(Rectangle((a * k, b * k), (c - a) * k, (d - b) * k, facecolor="none", edgecolor="orange",
                                   hatch="///", linewidth=0.6, alpha=0.8))
    if film.bar is not None:
        a, b, c, d = film.bar.box
        pad = 3
        ax.add_patch(Rectangle(((a - pad) * k, (b - pad) * k), (c - a + 2 * pad) * k, (d - b + 2 * pad) * k,
                               facecolor="none", edgecolor="magenta", linewidth=1.5))
        nm_per_px = film.nm_per_px if "from the scale bar" in film.scale else None
        used = f" = {film.bar.length_px * nm_per_px:.4g} nm" if nm_per_px is not None else ""
        ax.text((a + c) / 2 * k, (b - 2 * pad) * k, f"scale bar {film.bar.length_px:.1f} px{used}", color="magenta",
                ha="center", va="bottom", fontsize="small",
                bbox={"facecolor": "white", "edgecolor": "none", "alpha": 0.7, "pad": 1})


def save_overlay(film: MeasuredFilm, path, dpi: int | None = None, refused: list[str] | None = None) -> Path:
    """`overlay_figure`, written atomically at about the image's own resolution (or ``dpi``)."""

    w = film.image.shape[1]
    if dpi is None:
        dpi = int(min(300, max(100, round(w / 9.6))))
    return save_figure(overlay_figure(film, refused), path, dpi=dpi)


def overlay_figure(film: MeasuredFilm, refused: list[str] | None = None):
    """The detections drawn on the image (`save_overlay_axes`) with a title, the colour bar of the sizes and a
    scale bar: a matplotlib Figure 10 in wide. With ``refused`` (the reasons a picture is not a film of round
    particles) the title says so, in red, and the reasons follow it; the measurement's doubts are written under the
    title too."""

    h, w = film.image.shape
    det = film.detection
    width_in = 10.0
    image_in = 0.96 * width_in * h / w
    total_in = image_in + 1.2  # 0.35 in for the title above, 0.85 in for the key below
    fig = Figure(figsize=(width_in, total_in))
    FigureCanvasAgg(fig)
    ax = fig.add_axes((0.02, 0.85 / total_in, 0.96, image_in / total_in))
    save_overlay_axes(film, ax)
    ax.set_axis_off()
    s = film.summary
    size = (f"{s['mean_diameter_nm']:.1f} ± {s['sd_diameter_nm']:.1f} nm" if math.isfinite(s["nm_per_px"])
            else f"{s['mean_diameter_px']:.1f} ± {s['sd_diameter_px']:.1f} px")
    if refused:
        ax.set_title(f"{film.image.source}: refused, not a film of round particles ({s['dots']} objects found)",
                     fontsize="medium", color="firebrick")
    else:
        ax.set_title(f"{film.image.source}: {s['dots']} dots ({s['dots_cut_by_edge']} cut by the edge, dashed), "
                     f"d = {size}, σ = {100 * s['size_spread']:.1f} %, interior fraction {s['interior_fraction']:.2f}",
                     fontsize="medium")
    notes = list(refused or []) + [d for d in s.get("doubts", "").split("; ") if d]
    if notes:
        import textwrap

        text = "\n".join(textwrap.fill(("refused: " if refused and k < len(refused) else "doubt: ") + note, 140)
                         for k, note in enumerate(notes[:4]))
        ax.text(0.5, 1.0, text, transform=ax.transAxes, ha="center", va="top", fontsize="x-small",
                color="firebrick" if refused else "black", bbox={"facecolor": "white", "alpha": 0.8, "pad": 2})
    k, unit = (film.nm_per_px, "nm") if film.nm_per_px is not None else (1.0, "image px")
    sized = film_state(det.centres[~det.cut] * k, det.diameters[~det.cut] * k, (h * k, w * k))
    low, high = overlay_range(film)
    add_key(ax, sized, unit, diameters=(low * k, high * k),
            cax=fig.add_axes((0.3, 0.5 / total_in, 0.4, 0.12 / total_in)))
    return fig


#: ``save_side_by_side`` and ``side_by_side_figure`` are `qdots.inference.plots`'s since 0.3 (here until 0.4).
__getattr__ = moved_names(__name__, dict.fromkeys(("save_side_by_side", "side_by_side_figure"), "qdots.inference.plots"),
                          "0.3", "0.4")
