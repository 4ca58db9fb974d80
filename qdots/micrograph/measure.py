"""``qdots measure``: a micrograph in, a board, an overlay picture and a table of the thesis's metrics out.

`measure_image` reads the image (`read_micrograph`), settles its scale (the file's own, else the one
given, else the scale bar's), finds the dots (`detect_dots`), and measures the film (`film_metrics`,
with the film's LQE from the thesis's trap model). `measure` does that and writes, as one set
(`labrig.files.OutputSet`: all files or none), ``NAME.npz`` (a qdots state file that ``qdots
analyze`` and ``qdots render`` read), ``NAME_detections.png`` (the dots drawn on the image, coloured
by size with the thesis's key, cut dots dashed, a scale bar in nm) and ``NAME_summary.csv``.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from labrig.validate import InputError

from .detect import Detection, detect_dots
from .film import complete_neighbourhood, film_metrics, film_state
from .read import Micrograph, read_micrograph
from .admit import check_film, check_picture
from .annotations import Annotations, find_annotations
from .scale import ScaleBar, check_nm_per_px, parse_length, scale_from_bar

#: Diameters, nm, of quantum dots and nanocrystals: a scale that puts the dots outside says so (`scale_check`).
PLAUSIBLE_NM = (1.0, 100.0)
#: Trap draws of the film LQE (as ``qdots analyze``) on films of up to LQE_DOTS dots; larger films take
#: fewer (at least 2: their standard error is small anyway, and a draw costs seconds at 10^4 dots).
LQE_DRAWS, LQE_DOTS = 8, 2000


def lqe_draws(n_dots: int) -> int:
    """Trap draws of the film LQE of a film of ``n_dots`` dots: 8 up to 2,000 dots, then fewer, at least 2."""
    return max(2, min(LQE_DRAWS, LQE_DRAWS * LQE_DOTS // max(n_dots, 1)))


@dataclass(frozen=True)
class MeasuredFilm:
    """Everything `measure_image` found.

    Attributes
    ----------
    image : Micrograph
    detection : Detection
    state : qdots.State
        The board: image px, ``y`` up (`qdots.micrograph.film.film_state`).
    complete : ndarray of bool
        Dots whose neighbourhood lies inside the picture (`complete_neighbourhood`).
    nm_per_px : float or None
    scale : str
        Where the scale came from, in words.
    bar : ScaleBar or None
        The scale bar found on the image (used for the scale when its length was given).
    summary : dict
        `film_metrics` with ``coverage``, the film LQE and how the image was read.
    annotations : Annotations or None
        What was found drawn on the image and left out (`qdots.micrograph.annotations.find_annotations`).
    """

    image: Micrograph
    detection: Detection
    state: object
    complete: np.ndarray
    nm_per_px: float | None
    scale: str
    bar: ScaleBar | None
    summary: dict
    annotations: Annotations | None = None


def settle_scale(image: Micrograph, bar: ScaleBar | None, nm_per_px=None, scale_bar: str | None = None
                 ) -> tuple[float | None, str]:
    """The scale of ``image``: the file's own, else ``nm_per_px``, else read off the scale ``bar`` found on it
    (`qdots.micrograph.annotations.find_annotations`), ``scale_bar`` long (such as ``"200nm"``). Returns (nm per
    px or None, where it came from in words: the bar's length in px, where it is and what kind)."""
    if image.nm_per_px is not None:
        given = "" if nm_per_px is None and scale_bar is None else " (the scale given is not used: the file has one)"
        return image.nm_per_px, f"{image.nm_per_px:.4g} nm/px from the file's metadata{given}"
    if nm_per_px is not None:
        value = check_nm_per_px(nm_per_px)
        return value, f"{value:.4g} nm/px (given)"
    if scale_bar is not None:
        value = scale_from_bar(bar, scale_bar)
        return value, f"{value:.4g} nm/px from the scale bar: {scale_bar} over {describe_bar(bar)}"
    if bar is not None:
        return None, (f"none (sizes in px): a scale bar of {describe_bar(bar)}; give its length with "
                      "--scale-bar (such as --scale-bar 200nm), or the scale with --nm-per-px")
    return None, "none (sizes in px; give --nm-per-px or --scale-bar)"


def describe_bar(bar: ScaleBar) -> str:
    """``127 px (a solid bar at x 730-857, y 837-845 px)``."""
    x0, y0, x1, y1 = bar.box
    return f"{bar.length_px} px (a {'ruled' if bar.ruled else 'solid'} bar at x {x0}-{x1}, y {y0}-{y1} px)"


def scale_check(summary: dict) -> str:
    """One line on whether the scale makes the dots plausible nanocrystals (`PLAUSIBLE_NM` across)."""
    d = summary.get("mean_diameter_nm", math.nan)
    if not math.isfinite(summary["nm_per_px"]) or not math.isfinite(d):
        return "no scale: sizes are in px"
    low, high = PLAUSIBLE_NM
    if low <= d <= high:
        return f"dots {d:.3g} nm across: within the {low:g}-{high:g} nm of quantum dots and nanocrystals"
    return (f"dots {d:.3g} nm across, outside the {low:g}-{high:g} nm of quantum dots and nanocrystals: check the "
            f"scale ({summary['nm_per_px']:.4g} nm/px)")


def measure_image(path: str | os.PathLike, *, nm_per_px=None, scale_bar: str | None = None, polarity: str = "auto",
                  profile: str = "auto", page: int = 0, lqe: bool = True) -> MeasuredFilm:
    """Read a micrograph, find its dots and measure the film (nothing written).

    Parameters
    ----------
    path : path-like
        The image (see `qdots.micrograph.read` for the formats).
    nm_per_px : float, optional
        The scale, when the file has none.
    scale_bar : str, optional
        The length of the scale bar drawn on the image (``"200nm"``), when neither the file nor
        ``nm_per_px`` gives the scale.
    polarity : {"auto", "dark", "light"}
        Dots darker or lighter than the background (`detect_dots`).
    profile : {"auto", "sphere", "disc"}
        The dots' contrast profile (`detect_dots`).
    page : int
        Page of a multi-page file.
    lqe : bool
        Also compute the film LQE (thesis trap model, `qdots.analysis.lqe.film_lqe`).

    Raises
    ------
    labrig.validate.InputError
        Bad file or scale (one line), no dot found in the image, or a picture that is not a film of round
        particles (`qdots.micrograph.admit`).
    """
    from ..analysis.lqe import film_lqe

    if nm_per_px is not None:  # bad scales are refused before the image is read, even when the file has one
        check_nm_per_px(nm_per_px)
    if scale_bar is not None:
        parse_length(scale_bar)
    image = read_micrograph(path, page)
    found = find_annotations(image.pixels)
    check_picture(image.pixels, found, str(path))
    bar = found.bar
    scale, how = settle_scale(image, bar, nm_per_px, scale_bar)
    detection = detect_dots(image.pixels, polarity=polarity, profile=profile, ignore=found.ignore,
                            window=found.window)
    if detection.n_dots == 0:
        raise InputError(f"{path}: no dots found ({detection.polarity}); nothing written. Check --polarity, "
                         "or crop the image to the film")
    check_film(detection, str(path))
    state = film_state(detection.centres, detection.diameters, image.shape)
    h = image.shape[0]
    x0, y0, x1, y1 = detection.window
    complete = complete_neighbourhood(state, (x0, h - y1, x1, h - y0))
    summary = {"image": image.source, "page": image.page, "width_px": image.shape[1], "height_px": image.shape[0],
               "nm_per_px": scale if scale is not None else math.nan, "scale": how,
               "polarity": detection.polarity, "profile": detection.profile, "profile_p": detection.shape,
               "blur_px": detection.blur, "rejected_objects": detection.rejected,
               "dots_cut_by_edge": int(detection.cut.sum()), "coverage": detection.coverage(),
               "left_out": found.describe(float(image.pixels.min()), float(image.pixels.max()))}
    summary.update(film_metrics(state, measured=~detection.cut, complete=complete, nm_per_px=scale,
                                errors=detection.errors))
    summary["scale_check"] = scale_check(summary)
    if lqe:
        draws = lqe_draws(state.n_dots)
        average = film_lqe(state, draws=draws, seed=0)
        summary.update(lqe=average.mean, lqe_standard_error=average.standard_error, lqe_trap_draws=draws)
    return MeasuredFilm(image, detection, state, complete, scale, how, bar, summary, found)


def summary_rows(summary: dict) -> list[tuple[str, str]]:
    """The summary as (label, text) rows for `labrig.cli.print_table`."""
    s = summary
    nm = math.isfinite(s["nm_per_px"])
    size = (f"{s['mean_diameter_nm']:.1f} +- {s['sd_diameter_nm']:.1f} nm ({s['mean_diameter_px']:.2f} px)" if nm
            else f"{s['mean_diameter_px']:.2f} +- {s['sd_diameter_px']:.2f} px")
    rows = [
        ("scale", s["scale"]),
        ("scale check", s["scale_check"]),
        ("left out", s["left_out"]),
        ("dots", (f"{s['dots']} ({s['dots_cut_by_edge']} cut by the edge; {s['dots_complete']} with their whole "
                 f"neighbourhood in the picture)")),
        ("polarity", s["polarity"]),
        ("profile", f"{s['profile']}, blur {s['blur_px']:.2f} px"),
        ("coverage", f"{s['coverage']:.3f}"),
        ("mean diameter +- SD", size),
        ("size spread sigma (SD / mean)", (f"{100 * s['size_spread']:.1f} % (measured {100 * s['size_spread_measured']:.1f} %, "
                                           f"of which {100 * s['size_spread_error']:.1f} % is each diameter's "
                                           f"measurement error; from the interquartile range "
                                           f"{100 * s['size_spread_robust']:.1f} %)")),
        ("interior fraction (>= 5 neighbours)", f"{s['interior_fraction']:.3f}"),
        ("mean neighbours", f"{s['mean_neighbours']:.2f}"),
        ("psi6 local / global", f"{s['psi6_local']:.3f} / {s['psi6_global']:.3f}"),
        ("aggregates", f"{s['aggregates']} clusters of 5 or more dots; the largest cluster holds "
                       f"{100 * s['largest_share']:.1f} % of the dots"),
        ("single dots", f"{s['single_dots']}"),
        ("g(r) first peak", f"{s['gr_peak_diameters']:.2f} mean diameters"),
    ]
    if "lqe" in s:
        lqe = f"{s['lqe']:.4f} +- {s['lqe_standard_error']:.4f} ({s['lqe_trap_draws']} trap draws)"
        rows.append(("film LQE (traps 1/3, R_F = mean d)", lqe))
    rows.append(("objects that are not dots", f"{s['rejected_objects']} (text, scale-bar strokes, debris)"))
    return rows


def draw_scale_bar(ax, nm_per_px: float | None, width_px: float, height_px: float, y_down: bool = True) -> None:
    """A white-on-black scale bar of a round length (about a fifth of the width) in the lower left corner."""
    from matplotlib.patches import Rectangle

    from ..render import nice_length

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


def save_overlay_axes(film: MeasuredFilm, ax, extent_nm: tuple[float, float] | None = None) -> None:
    """Draw the image and its detections on ``ax``: circles coloured by size (`qdots.render.size_colours`),
    dashed white for dots cut by the edge, centres as yellow crosses, a scale bar. With ``extent_nm`` the
    axes run in nm (row 0 at the top), else in image px."""
    from matplotlib.collections import PatchCollection
    from matplotlib.patches import Circle

    from ..render import size_colours

    h, w = film.image.shape
    det = film.detection
    k = 1.0 if extent_nm is None else extent_nm[0] / w
    ax.imshow(film.image.pixels, cmap="gray", extent=(0, w * k, h * k, 0), interpolation="nearest")
    whole = ~det.cut
    colours = size_colours(0.5 * det.diameters[whole]) if whole.any() else np.zeros((0, 3))
    ax.add_collection(PatchCollection([Circle(c * k, 0.5 * d * k) for c, d in zip(det.centres[whole],
                                                                                 det.diameters[whole])],
                                      facecolor="none", edgecolor=colours, linewidth=1.2))
    ax.add_collection(PatchCollection([Circle(c * k, 0.5 * d * k) for c, d in zip(det.centres[det.cut],
                                                                                 det.diameters[det.cut])],
                                      facecolor="none", edgecolor="white", linewidth=0.9, linestyle="--"))
    ax.plot(det.centres[:, 0] * k, det.centres[:, 1] * k, "+", color="yellow", markersize=3, markeredgewidth=0.6)
    mark_annotations(ax, film, k)
    draw_scale_bar(ax, film.nm_per_px / k if film.nm_per_px is not None else None, w * k, h * k)
    ax.set_xlim(0, w * k)
    ax.set_ylim(h * k, 0)


def mark_annotations(ax, film: MeasuredFilm, k: float = 1.0) -> None:
    """Shade what was left out (strips, label boxes) and outline the scale bar, with its length in px and, when
    it gave the scale, in nm (``k``: axes units per image px)."""
    from matplotlib.patches import Rectangle

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
        from_bar = film.nm_per_px is not None and "from the scale bar" in film.scale
        used = f" = {film.bar.length_px * film.nm_per_px:.4g} nm" if from_bar else ""
        ax.text((a + c) / 2 * k, (b - 2 * pad) * k, f"scale bar {film.bar.length_px} px{used}", color="magenta",
                ha="center", va="bottom", fontsize="small",
                bbox={"facecolor": "white", "edgecolor": "none", "alpha": 0.7, "pad": 1})


def save_overlay(film: MeasuredFilm, path, dpi: int | None = None) -> Path:
    """`overlay_figure`, written atomically at about the image's own resolution (or ``dpi``)."""
    from labrig.figures import save_figure

    w = film.image.shape[1]
    if dpi is None:
        dpi = int(min(300, max(100, round(w / 9.6))))
    return save_figure(overlay_figure(film), path, dpi=dpi)


def overlay_figure(film: MeasuredFilm):
    """The detections drawn on the image (`save_overlay_axes`) with a title, the colour bar of the sizes and a
    scale bar: a matplotlib Figure 10 in wide."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from ..render import add_key

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
    ax.set_title(f"{film.image.source}: {s['dots']} dots ({s['dots_cut_by_edge']} cut by the edge, dashed), "
                 f"d = {size}, σ = {100 * s['size_spread']:.1f} %, interior fraction {s['interior_fraction']:.2f}",
                 fontsize="medium")
    k, unit = (film.nm_per_px, "nm") if film.nm_per_px is not None else (1.0, "image px")
    sized = film_state(det.centres[~det.cut] * k, det.diameters[~det.cut] * k, (h * k, w * k))
    add_key(ax, sized, unit, cax=fig.add_axes((0.3, 0.5 / total_in, 0.4, 0.12 / total_in)))
    return fig


def state_metadata(film: MeasuredFilm) -> dict:
    """What a measured board's state file records of its image (`qdots.io.checkpoint.save_board`'s ``extra``)."""
    return {"micrograph": {"image": film.image.source, "page": film.image.page, "nm_per_px": film.nm_per_px,
                           "scale": film.scale, "polarity": film.detection.polarity,
                           "profile": film.detection.profile,
                           "cut": np.flatnonzero(film.detection.cut).tolist(),
                           "window_px": list(film.detection.window)}}


def measure(path: str | os.PathLike, out: str | os.PathLike | None = None, *, name: str | None = None,
            nm_per_px=None, scale_bar: str | None = None, polarity: str = "auto", profile: str = "auto",
            page: int = 0, lqe: bool = True) -> MeasuredFilm:
    """`measure_image`, then write ``NAME.npz``, ``NAME_detections.png`` and ``NAME_summary.csv`` into ``out``
    (default: beside the image) as one set. ``NAME`` defaults to the image's stem. Nothing is written when the
    image is refused or holds no dot."""
    from labrig.files import OutputSet, slug, write_csv

    from ..io import checkpoint

    path = Path(path)
    film = measure_image(path, nm_per_px=nm_per_px, scale_bar=scale_bar, polarity=polarity, profile=profile,
                         page=page, lqe=lqe)
    stem = slug(name if name is not None else path.stem)
    out = path.parent if out is None else Path(out)
    with OutputSet(out, stem) as files:
        checkpoint.save_board(film.state, files.stage(f"{stem}.npz"), state_metadata(film))
        save_overlay(film, files.stage(f"{stem}_detections.png"))
        write_csv(files.stage(f"{stem}_summary.csv"), [film.summary])
    return film
