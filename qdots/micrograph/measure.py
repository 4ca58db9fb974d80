"""``qdots measure``: a micrograph in, a board, an overlay picture and a table of the thesis's metrics out.

`measure_image` reads the image (`read_micrograph`), settles its scale (the file's own, else the one
given, else the scale bar's), finds the dots (`detect_dots`), and measures the film (`film_metrics`,
with the film's LQE from the thesis's trap model), and returns a `MeasuredFilm`: it writes nothing.
`qdots.micrograph.overlay` draws it and `qdots.cli.files` writes ``qdots measure``'s files
(``NAME.npz``, a qdots state file that ``qdots analyze`` and ``qdots render`` read,
``NAME_detections.png`` and ``NAME_summary.csv``).
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Iterable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from labrig.progress import StageLines, progress_bar
from labrig.threads import run_tasks
from labrig.validate import InputError

from ..analysis.lqe import film_lqe
from ..geometry import nearest_ratio
from ..state import State
from .admit import (
    MAX_OUTLINE,
    MAX_TAKEN_ELONGATION,
    MIN_FILM_DOTS,
    ROUND_OUTLINE,
    TAKEN_REACH,
    NotAFilm,
    as_taken,
    check_picture,
    clearest_dots,
    film_verdict,
)
from .annotations import Annotations, find_annotations
from .bar import ScaleBar
from .cells import network_cells
from .detect import MAX_SMOOTHING, STAGES, Detection, detect_dots
from .film import OUTLIER, complete_neighbourhood, film_metrics, film_state, size_inliers
from .read import Micrograph, read_micrograph
from .scale import check_nm_per_px, parse_length, scale_from_bar
from .shapes import STACKED

#: Diameters, nm, of quantum dots and nanocrystals: a scale that puts the dots outside says so (`scale_check`).
PLAUSIBLE_NM = (1.0, 100.0)
#: A refused detection is sought again on the picture smoothed by these shares of the median diameter of what it found
#: (`smoothed_retry`), where what it finds must have outlines under `qdots.micrograph.admit.ROUND_OUTLINE`. Measured on
#: the development half of the EMPS films: 8 of the 19 refused films of round particles (texture or shading had cut each
#: particle into 1.6-200 pieces) are films, outlines 0.03-0.096; two pictures of rods and shards, 0.106 and 0.120.
RETRY_SMOOTHING = (0.5, 1.0)
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
        `film_metrics` with ``coverage``, the film LQE, how the image was read and ``doubts`` (what makes the
        measurement doubtful, in words, ``"; "`` between them; empty when nothing does).
    annotations : Annotations or None
        What was found drawn on the image and left out (`qdots.micrograph.annotations.find_annotations`).
    stacked : ndarray of bool or None
        Dots stacked on a neighbour (`qdots.micrograph.shapes.STACKED`: overlapping it by over a third, which no
        particle in one layer can: a second layer, a piece of something larger, or not a particle), left out of the
        size statistics as the dots the edge cuts are.
    """

    image: Micrograph
    detection: Detection
    state: State
    complete: np.ndarray
    nm_per_px: float | None
    scale: str
    bar: ScaleBar | None
    summary: dict
    annotations: Annotations | None = None
    stacked: np.ndarray | None = None


def settle_scale(image: Micrograph, bar: ScaleBar | None, nm_per_px=None, scale_bar: str | None = None
                 ) -> tuple[float | None, str]:
    """The scale of ``image``: the file's own, else ``nm_per_px``, else read off the scale ``bar`` found on it
    (`qdots.micrograph.annotations.find_annotations`), ``scale_bar`` long (such as ``"200nm"``). Returns (nm per
    px or None, where it came from in words: the bar's length in px, where it is and what kind)."""
    if image.nm_per_px is not None:
        given = "" if nm_per_px is None and scale_bar is None else " (the scale given is not used: the file has one)"
        where = image.scale_source or "the file's metadata"
        return image.nm_per_px, f"{image.nm_per_px:.4g} nm/px from {where}{given}"
    if nm_per_px is not None:
        value = check_nm_per_px(nm_per_px)
        return value, f"{value:.4g} nm/px (given)"
    if scale_bar is not None:
        value = scale_from_bar(bar, scale_bar)
        assert bar is not None  # scale_from_bar refuses a missing bar
        return value, f"{value:.4g} nm/px from the scale bar: {scale_bar} over {describe_bar(bar)}"
    if bar is not None:
        return None, (f"none (sizes in px): a scale bar of {describe_bar(bar)}; give its length with "
                      "--scale-bar (such as --scale-bar 200nm), or the scale with --nm-per-px")
    return None, "none (sizes in px; give --nm-per-px or --scale-bar)"


def describe_bar(bar: ScaleBar) -> str:
    """``127 px (a solid bar at x 730-857, y 837-845 px)``."""
    x0, y0, x1, y1 = bar.box
    edge = "; it reaches the picture's edge, so it may be longer than shown: check it" if bar.at_edge else ""
    return (f"{bar.length_px:.1f} px {bar.measured} (a {'ruled' if bar.ruled else 'solid'} bar at x {x0}-{x1}, "
            f"y {y0}-{y1} px{edge})")


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
                  profile: str = "auto", page: int = 0, lqe: bool = True, force: bool = False,
                  progress: bool | str = False) -> MeasuredFilm:
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
    force : bool
        Measure a picture whose dots do not look like a film of round particles (`qdots.micrograph.admit`) anyway;
        the summary's ``doubts`` then say why it would have been refused.
    progress : bool or "lines"
        Show a progress bar of the stages on stderr (it says when numba compiles, the first run on a machine), or
        with ``"lines"`` (for logs and pipes) a line per stage once the run takes longer than a few seconds
        (`labrig.progress.StageLines`).

    Raises
    ------
    labrig.validate.InputError
        Bad file or scale (one line), or no dot found in the image.
    qdots.micrograph.admit.NotAFilm
        A picture that is not a film of round particles (one line with the reasons; unless ``force``); its ``found``
        holds what was found, for an overlay.
    """

    if nm_per_px is not None:  # bad scales are refused before the image is read, even when the file has one
        check_nm_per_px(nm_per_px)
    if scale_bar is not None:
        parse_length(scale_bar)
    shown_as = (StageLines("qdots measure") if progress == "lines" else
                progress_bar(3 + len(STAGES), unit="stage", desc="qdots measure", show=bool(progress), leave=False))
    with shown_as as shown:
        def step(stage: str) -> None:
            shown.set_postfix_str(stage, refresh=False)
            shown.update()

        image = read_micrograph(path, page)
        step("finding what is drawn on the picture")
        found = find_annotations(image.pixels)
        if not force:
            check_picture(image.pixels, found, str(path))
        scale, how = settle_scale(image, found.bar, nm_per_px, scale_bar)
        step("finding the dots")
        detection = detect_dots(image.pixels, polarity=polarity, profile=profile, ignore=found.ignore,
                                window=found.window, step=step)
        step("measuring the film")
        refusals, doubts = film_verdict(detection) if detection.n_dots else (["no dots found"], [])
        if refusals and polarity == "auto":  # the other phase may be the film: dark particles joined by necks, light gaps
            step(f"the {'light' if detection.dark else 'dark'} objects (the {'dark' if detection.dark else 'light'} "
                 "ones are not a film of round particles)")
            other = detect_dots(image.pixels, polarity="light" if detection.dark else "dark", profile=profile,
                                ignore=found.ignore, window=found.window, screen=refused if detection.n_dots else None)
            refused_too = bool(other.n_dots) and bool(film_verdict(other)[0])
            if other.n_dots and (not refused_too or not detection.n_dots):
                was = "darker" if detection.dark else "lighter"
                detection = replace(other, polarity=f"{other.polarity.replace(' (given)', '')} (automatic: the {was} "
                                                    f"objects are not a film of round particles ({refusals[0]})"
                                                    f"{', nor are these' if refused_too else ', these are'})")
                refusals, doubts = film_verdict(detection)
        if refusals and detection.n_dots:  # particles with inner texture or shading cut into pieces: smoothed more
            detection, refusals, doubts = smoothed_retry(image.pixels, detection, refusals, doubts, found, polarity,
                                                         profile, step)
        if refusals:  # touching particles cut into pieces however smoothed: the cells their gaps' network encloses
            detection, refusals, doubts = cells_retry(image.pixels, detection, refusals, doubts, found, polarity, step)
        if refusals:  # a few particles on a support speckled with faint features: the clearest dots
            detection, refusals, doubts = clearest_retry(detection, refusals, doubts)
    if detection.n_dots == 0:
        raise InputError(f"{path}: no dots found ({detection.polarity}); nothing written. Check --polarity, "
                         "or crop the image to the film")
    if refusals and force:
        doubts = [f"measured with --force, though not a film of round particles: {r}" for r in refusals] + doubts
    film = measured_film(image, detection, scale, how, found.bar, found, lqe and not (refusals and not force), doubts)
    if refusals and not force:
        flip = "dark" if not detection.dark else "light"
        raise NotAFilm(f"{path}: not a film of round particles: {'; '.join(refusals)} (the {detection.polarity.split()[0]}"
                       f" objects; if the particles are the {flip} ones, try --polarity {flip})", refusals, film)
    return film


def refused(detection: Detection, most_whole: int, max_outline: float = MAX_OUTLINE) -> bool:
    """Whether ``detection``, the dots as first found, is not a film of round particles and no fit can make it one: the
    ``screen`` of the detections whose dots are kept only if they are a film (`qdots.micrograph.detect.detect_dots`),
    which stops there. Either the search cannot end with `qdots.micrograph.admit.MIN_FILM_DOTS` whole dots
    (``most_whole``, `qdots.micrograph.detect.most_whole`: a bound, not a guess), or it shows that many and
    `qdots.micrograph.admit.film_verdict` refuses them. With fewer whole dots, within the bound, it does not stop: the
    count is the one verdict the search for faint dots (after the settling) can overturn, and does (on the development
    halves, retries grew from 8 to 10 whole dots, EMPS d04d7ced9f, and from 5 to 10, e1adc2ba25; on the test half a
    film was lost when the count was screened: EMPS 88808139d3, 6 as first found, 10 fitted). Not the first detection
    either: there the fits change the verdict (EMPS 891f96f60d's outlines wander 18 % as first found and 13 %
    fitted)."""
    if most_whole < MIN_FILM_DOTS:
        return True
    return int(np.count_nonzero(~detection.cut)) >= MIN_FILM_DOTS and bool(film_verdict(detection, max_outline)[0])


def smoothed_retry(pixels: np.ndarray, detection: Detection, refusals: list[str], doubts: list[str],
                   found: Annotations, polarity: str, profile: str, step) -> tuple[Detection, list[str], list[str]]:
    """A refused ``detection`` found again on the picture smoothed by `RETRY_SMOOTHING` times the median diameter of
    what it found, in its polarity and then (``polarity="auto"``) the other: pieces of particles with an inner texture,
    shading or a rough surface rejoin the particles they belong to. Smoothing rounds every outline (rods and shards
    too), so the objects found must be clearly round (a median outline under `qdots.micrograph.admit.ROUND_OUTLINE`
    rather than `qdots.micrograph.admit.MAX_OUTLINE`), and round in the picture as taken, where their necks are read
    too (`qdots.micrograph.admit.as_taken`). The first that is a film of round particles is kept, saying so;
    if none is, the refused one is kept, with its ``refusals`` and ``doubts`` (`first_film`), and what was elongated
    as taken is said."""
    whole = ~detection.cut
    pieces = float(np.median(detection.diameters[whole if whole.any() else slice(None)]))
    elongated: list[str] = []

    def attempts():
        for share in RETRY_SMOOTHING:
            smoothing = float(np.clip(share * pieces, 1.5, MAX_SMOOTHING))
            for dark in phases(detection, polarity):
                step(f"smoothing by {smoothing:.1f} px ({'dark' if dark else 'light'} dots)")
                other: Detection | None = detect_dots(
                    pixels, polarity="dark" if dark else "light", profile=profile, ignore=found.ignore,
                    window=found.window, smoothing=smoothing,
                    screen=lambda first, most: most < MIN_FILM_DOTS or refused(as_taken(pixels, first, found.ignore)[1],
                                                                              most, ROUND_OUTLINE))
                if other is not None and other.n_dots:
                    taken, other = as_taken(pixels, other, found.ignore)
                if other is not None and other.n_dots and not film_verdict(other, ROUND_OUTLINE)[0]:
                    if taken > MAX_TAKEN_ELONGATION:
                        elongated.append(f"smoothed by {smoothing:.1f} px, the objects look round, but in the picture "
                                         f"as taken they are elongated: {taken:.2f} times as long as wide within "
                                         f"{TAKEN_REACH:g} radii of each (median; round particles: under "
                                         f"{MAX_TAKEN_ELONGATION:g}): rods, wires?")
                        other = None
                shown = f"{'dark' if dark else 'light'} dots ({'given' if polarity != 'auto' else 'automatic'}"
                yield other, ROUND_OUTLINE, (f"{shown}: smoothed by {smoothing:.1f} px, as the objects found at first "
                                             f"were not a film of round particles ({refusals[0].split(' (')[0]}); "
                                             "these are)")

    kept, reasons, worries = first_film(detection, refusals, doubts, attempts())
    return kept, (reasons + elongated[:1] if kept is detection else reasons), worries


def cells_retry(pixels: np.ndarray, detection: Detection, refusals: list[str], doubts: list[str], found: Annotations,
                polarity: str, step) -> tuple[Detection, list[str], list[str]]:
    """A refused ``detection`` (after `smoothed_retry`) found again as the cells of a network
    (`qdots.micrograph.cells.network_cells`), in its polarity and then (``polarity="auto"``) the other: close-packed
    particles whose gaps form one network, or touch in a lattice. The first that is a film of round particles is kept,
    saying so; if none is, the refused one is kept, with its ``refusals`` and ``doubts`` (`first_film`)."""
    def attempts():
        for dark in phases(detection, polarity):
            step(f"the cells of a network ({'dark' if dark else 'light'} particles)")
            other = network_cells(pixels, found.ignore, found.window, dark)
            yield other, MAX_OUTLINE, "" if other is None else (
                f"{other.polarity} ({'given' if polarity != 'auto' else 'automatic'}: the objects found as dots were "
                f"not a film of round particles ({refusals[0].split(' (')[0]}); these are)")

    return first_film(detection, refusals, doubts, attempts())


def clearest_retry(detection: Detection, refusals: list[str], doubts: list[str]) -> tuple[Detection, list[str], list[str]]:
    """A refused ``detection`` (after every other retry) kept to its clearest dots (`qdots.micrograph.admit.clearest_dots`:
    a few particles on a support speckled with faint, irregular features); kept when they are a film of round
    particles, saying so and how many faint objects were left out (counted with the rejected objects); if not, the
    refused one with its ``refusals`` and ``doubts`` (`first_film`)."""
    def attempts():
        found = clearest_dots(detection)
        if found is not None:
            keep, gap = found
            left = int(np.count_nonzero(~keep))
            clear = replace(detection.take(keep), rejected=detection.rejected + left)
            yield clear, MAX_OUTLINE, (f"{detection.polarity}; the {clear.n_dots} clearest dots kept, {gap:.1f} times "
                                       f"the contrast of the {left} faint objects left out (all together they were not "
                                       f"a film of round particles: {refusals[0].split(' (')[0]})")

    return first_film(detection, refusals, doubts, attempts())


def phases(detection: Detection, polarity: str) -> list[bool]:
    """Whether the particles are dark, in the order a retry tries: ``detection``'s, then (``polarity="auto"``) the
    other."""
    return [detection.dark] if polarity != "auto" else [detection.dark, not detection.dark]


def first_film(detection: Detection, refusals: list[str], doubts: list[str],
               attempts: Iterable[tuple[Detection | None, float, str]]) -> tuple[Detection, list[str], list[str]]:
    """The first of ``attempts`` (each a detection or None, the largest median outline it may have, and the
    ``polarity`` note that says how it was found) that is a film of round particles, with its note and
    `qdots.micrograph.admit.film_verdict`; if none is, the refused ``detection`` with its ``refusals`` and ``doubts``.
    The attempts are made one at a time, up to the first film."""
    for other, max_outline, note in attempts:
        if other is not None and other.n_dots and not film_verdict(other, max_outline)[0]:
            return replace(other, polarity=note), *film_verdict(other)
    return detection, refusals, doubts


def measured_film(image: Micrograph, detection: Detection, scale: float | None, how: str, bar: ScaleBar | None,
                  found: Annotations, lqe: bool, doubts: list[str]) -> MeasuredFilm:
    """The board and the summary of the dots found in ``image`` (see `measure_image`), with the ``doubts`` about it
    (`qdots.micrograph.admit.film_verdict`)."""
    state = film_state(detection.centres, detection.diameters, image.shape)
    h = image.shape[0]
    x0, y0, x1, y1 = detection.window
    complete = complete_neighbourhood(state, (x0, h - y1, x1, h - y0))
    stacked = nearest_ratio(detection.centres, detection.diameters) < STACKED
    summary: dict[str, Any] = {"image": image.source, "page": image.page, "width_px": image.shape[1], "height_px": image.shape[0],
               "nm_per_px": scale if scale is not None else math.nan, "scale": how,
               "polarity": detection.polarity, "profile": detection.profile, "profile_p": detection.shape,
               "blur_px": detection.blur, "rejected_objects": detection.rejected,
               "dots_cut_by_edge": int(detection.cut.sum()), "dots_stacked": int(stacked.sum()),
               "coverage": detection.coverage(),
               "left_out": found.describe(float(image.pixels.min()), float(image.pixels.max())),
               "doubts": "; ".join(doubts)}
    draws = lqe_draws(state.n_dots) if lqe else 0
    tasks: list[Callable[[], Any]] = [  # the film LQE beside the metrics, in a second thread (its products release the GIL)
        lambda: film_lqe(state, draws=draws, seed=0) if lqe else None,
        lambda: film_metrics(state, measured=~detection.cut & ~stacked, complete=complete, nm_per_px=scale,
                             errors=detection.errors)]
    average, metrics = run_tasks(tasks) if lqe else (None, tasks[1]())  # (the metrics' own tasks then in two threads)
    summary.update(metrics)
    sized = ~detection.cut & ~stacked  # the half-depth widths of the dots the mean diameter is of, outliers left out
    half = detection.half_widths()[sized][size_inliers(detection.diameters[sized])]
    summary["mean_half_width_px"] = float(half.mean()) if half.size else math.nan
    if scale is not None:
        summary["mean_half_width_nm"] = summary["mean_half_width_px"] * scale
    summary["scale_check"] = scale_check(summary)
    if average is not None:
        summary.update(lqe=average.mean, lqe_standard_error=average.standard_error, lqe_trap_draws=draws)
    return MeasuredFilm(image, detection, state, complete, scale, how, bar, summary, found, stacked)


def summary_rows(summary: dict) -> list[tuple[str, str]]:
    """The summary as (label, text) rows for `labrig.cli.print_table`."""
    s = summary
    nm = math.isfinite(s["nm_per_px"])
    size = (f"{s['mean_diameter_nm']:.1f} +- {s['sd_diameter_nm']:.1f} nm ({s['mean_diameter_px']:.2f} px)" if nm
            else f"{s['mean_diameter_px']:.2f} +- {s['sd_diameter_px']:.2f} px")
    populations = ""
    if s.get("size_populations") == 2:
        k, unit = (s["nm_per_px"], "nm") if nm else (1.0, "px")
        populations = "; ".join(f"{100 * s[f'{p}_share']:.0f} % at {k * s[f'{p}_mean_diameter_px']:.3g} {unit} "
                                f"(sigma {100 * s[f'{p}_spread']:.1f} %)" for p in ("small", "large"))
    rows = [
        ("scale", s["scale"]),
        ("scale check", s["scale_check"]),
        ("left out", s["left_out"]),
        ("dots", (f"{s['dots']} ({s['dots_cut_by_edge']} cut by the edge; {s['dots_complete']} with their whole "
                 f"neighbourhood in the picture)")),
        ("left out of the sizes", (f"{s['dots_stacked']} dots stacked on a neighbour (overlapping it by over a third: "
                                   f"a second layer, or not particles); {s['size_outliers']} sizes over "
                                   f"{OUTLIER:g} robust deviations from the median")),
        ("polarity", s["polarity"]),
        ("profile", s["profile"] + (f", blur {s['blur_px']:.2f} px" if math.isfinite(s["blur_px"]) else "")),
        ("coverage", f"{s['coverage']:.3f}"),
        ("mean diameter +- SD", size),
        ("half-depth width", (f"{s['mean_half_width_nm']:.1f} nm" if nm else f"{s['mean_half_width_px']:.2f} px")
         + " (each dot's width at half depth on its own profile, as a line profile measures it)"),
        ("size spread sigma (SD / mean)", (f"{100 * s['size_spread']:.1f} % (measured {100 * s['size_spread_measured']:.1f} %, "
                                           f"of which {100 * s['size_spread_error']:.1f} % is each diameter's "
                                           f"measurement error; from the interquartile range "
                                           f"{100 * s['size_spread_robust']:.1f} %)")),
        *([("two size populations", populations)] if populations else []),
        ("interior fraction (>= 5 neighbours)", f"{s['interior_fraction']:.3f}"),
        ("mean neighbours", f"{s['mean_neighbours']:.2f}"),
        ("psi6 local / global", f"{s['psi6_local']:.3f} / {s['psi6_global']:.3f}"),
        ("aggregates", f"{s['aggregates']} cluster{'' if s['aggregates'] == 1 else 's'} of 5 or more dots; the "
                       "largest cluster holds "
                       f"{100 * s['largest_share']:.1f} % of the dots"),
        ("single dots", f"{s['single_dots']}"),
        ("g(r) first peak", f"{s['gr_peak_diameters']:.2f} mean diameters"),
    ]
    if "lqe" in s:
        lqe = f"{s['lqe']:.4f} +- {s['lqe_standard_error']:.4f} ({s['lqe_trap_draws']} trap draws)"
        rows.append(("film LQE (traps 1/3, R_F = mean d)", lqe))
    rows.append(("objects that are not dots", f"{s['rejected_objects']} (text, scale-bar strokes, debris)"))
    rows += [("doubt", doubt) for doubt in s["doubts"].split("; ") if doubt]
    return rows


def state_metadata(film: MeasuredFilm) -> dict:
    """What a measured board's state file records of its image (`qdots.io.checkpoint.save_board`'s ``extra``)."""
    return {"micrograph": {"image": film.image.source, "page": film.image.page, "nm_per_px": film.nm_per_px,
                           "scale": film.scale, "polarity": film.detection.polarity,
                           "profile": film.detection.profile,
                           "cut": np.flatnonzero(film.detection.cut).tolist(),
                           "window_px": list(film.detection.window)}}
