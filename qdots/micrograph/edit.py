"""A measured film measured again from a set of dots corrected by hand (dots added, deleted, moved or resized).

This is what the napari plugin's *Measure the edited dots* does (`qdots.napari_plugin`), and what a script can do
with a corrected list. A dot kept as it was measured (centre and diameter within `SAME` px of a measured dot)
keeps its fit: contrast, measurement error, the shape of its region. A dot added, moved or resized takes the
centre and diameter given for it, without a fit, and the median measurement error of the film. The film's
metrics (coverage, sizes and spread, neighbours, psi6, g(r), the film LQE) are then measured on the edited set
exactly as `qdots.micrograph.measure.measure_image` measures a detection, and the summary says how many dots
were edited (``dots_edited``, ``dots_deleted``, and a doubt in words).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from labrig.validate import InputError

from ..geometry import nearest_centre
from ..limits import MAX_DOTS
from .admit import film_verdict
from .annotations import Annotations
from .detect import cut_dots
from .measure import MeasuredFilm, measured_film

#: Largest change of centre or diameter, px, under which an edited dot is the measured one.
SAME = 0.5


def edited_film(film: MeasuredFilm, centres, diameters, *, lqe: bool = False) -> MeasuredFilm:
    """``film`` measured again with the dots at ``centres`` with ``diameters`` (see the module).

    Parameters
    ----------
    film : MeasuredFilm
        A measurement (`qdots.micrograph.measure.measure_image`), or what a refusal found (`NotAFilm.found`).
    centres : array_like, shape (N, 2)
        ``(x, y)`` = (column, row) of each dot, image px, inside the image.
    diameters : array_like, shape (N,)
        Each dot's diameter, px, > 0.
    lqe : bool
        Also compute the film LQE (seconds on large films).

    Returns
    -------
    MeasuredFilm
        Its summary has ``dots_edited`` (dots added, moved or resized) and ``dots_deleted`` (measured dots no longer
        in the set).

    Raises
    ------
    labrig.validate.InputError
        No dots, more than `qdots.limits.MAX_DOTS`, shapes that do not match, a centre outside the image, a
        diameter that is not a positive finite number.
    """
    centres = np.asarray(centres, dtype=float)
    diameters = np.asarray(diameters, dtype=float)
    if centres.ndim != 2 or centres.shape[1:] != (2,) or diameters.shape != (len(centres),):
        raise InputError(f"centres must be (N, 2) and diameters (N,), got {centres.shape} and {diameters.shape}")
    if not 1 <= len(centres) <= MAX_DOTS:
        raise InputError(f"the edited set must hold 1 to {MAX_DOTS:,} dots, got {len(centres):,}")
    h, w = film.image.shape
    inside = np.isfinite(centres).all(axis=1) & (centres[:, 0] >= 0) & (centres[:, 0] <= w) & (centres[:, 1] >= 0) & (
        centres[:, 1] <= h)
    if not inside.all():
        k = int(np.flatnonzero(~inside)[0])
        raise InputError(f"dot {k}'s centre {tuple(centres[k])} lies outside the {w} x {h} px image")
    if not (np.isfinite(diameters) & (diameters > 0)).all():
        raise InputError("every diameter must be a positive number of px")
    det = film.detection
    distance, index = nearest_centre(centres, det.centres)
    kept = distance <= SAME
    if det.n_dots:
        kept &= np.abs(diameters - det.diameters[index]) <= SAME
    index = np.where(kept, index, 0)
    found = film.annotations if film.annotations is not None else Annotations(det.window)
    edge_cut = cut_dots(centres, diameters, det.window, found.ignore)
    error = float(np.median(det.errors)) if det.errors.size else 0.0
    edited = replace(det, centres=centres, diameters=diameters,
                     cut=np.where(kept, det.cut[index] if det.n_dots else False, edge_cut),
                     contrast=np.where(kept, det.contrast[index] if det.n_dots else np.nan, np.nan),
                     errors=np.where(kept, det.errors[index] if det.n_dots else error, error),
                     shapes=np.where(kept[:, None], det.shapes[index] if det.n_dots else np.nan, np.nan),
                     widths=None if det.widths is None else np.where(kept, det.widths[index] if det.n_dots else np.nan,
                                                                      np.nan))
    changed = int(np.count_nonzero(~kept))
    deleted = det.n_dots - len(np.unique(index[kept]))
    refusals, doubts = film_verdict(edited)
    doubts = [f"not a film of round particles: {reason}" for reason in refusals] + doubts
    if changed or deleted:
        doubts.append(f"edited by hand: {changed} dots added, moved or resized (their sizes as given, not fitted), "
                      f"{deleted} measured dots deleted or changed")
    result = measured_film(film.image, edited, film.nm_per_px, film.scale, film.bar, found, lqe, doubts)
    result.summary.update(dots_edited=changed, dots_deleted=deleted)
    return result
