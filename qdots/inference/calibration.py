"""Are the posteriors of ``qdots infer`` honest? Coverage of their credible intervals on micrographs of known films.

Held-out films (`qdots.inference.library.prior_point` of the ``"calibration"`` stream: drawn from the prior
like the training films, none of them among those) are simulated, drawn as bright-field micrographs
(`board_micrograph`: `qdots.micrograph.synthetic.render_micrograph` at 2 image px per board px, so the dots
are about 30 px across as on the shared micrograph, with blur, uneven light, the support's grain and noise),
written as PNG and measured by `qdots.micrograph.measure.measure_image`, exactly as a user's image is. The
posterior at each measured film gives a central 90 % interval per parameter, calibrated
(`qdots.inference.conformal`) and as the networks give it; `coverage_table` counts how often each holds the
truth. These films are not the library films the calibration was fitted on, so the count tests it. An honest
posterior holds it in about 90 % of the films; the issue asks 80-97 % for each parameter called identifiable.
The same films measured directly on their boards (no picture) separate what the imaging costs from what the
network gets wrong.
"""

from __future__ import annotations

import math
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from labrig.validate import InputError

from ..io import checkpoint
from ..micrograph.measure import measure_image
from ..micrograph.synthetic import render_micrograph
from .forward import PARAMETERS, film_measures, image_measures, parameter_keys
from .library import observation, prior_point, run_points
from .posterior import Posterior, credible_intervals

#: How the calibration's micrographs are drawn: image px per board px, and the imaging
#: (`qdots.micrograph.synthetic.render_micrograph`).
SCALE = 2.0
IMAGING: dict[str, Any] = {"noise": 0.05, "blur": 1.0, "contrast": 0.55, "contrast_spread": 0.12, "illumination": 0.3,
           "texture": 0.02}


def board_micrograph(state, seed: int = 0, scale: float = SCALE) -> np.ndarray:
    """A bright-field micrograph (grey, values about 0-1) of a simulated board: image rows down, ``scale`` image px
    per board px."""
    w, h = state.box
    shape = (int(math.ceil(h * scale)), int(math.ceil(w * scale)))
    centres = np.column_stack([state.positions[:, 0] * scale, (h - state.positions[:, 1]) * scale])
    return render_micrograph(centres, 2.0 * state.radii * scale, shape, seed=seed, **IMAGING)


def write_png(pixels: np.ndarray, path: str | os.PathLike) -> Path:
    """``pixels`` (about 0-1) as an 8-bit grey PNG."""
    import imageio.v3 as iio

    out = Path(path)
    iio.imwrite(out, (np.clip(pixels, 0.0, 1.0) * 255).round().astype(np.uint8))
    return out


@dataclass(frozen=True)
class CalibrationFilm:
    """One held-out film: its point (the truth), and the posterior's intervals from its micrograph and its board,
    and the networks' own (uncalibrated) intervals from its micrograph."""

    point: dict
    image: list
    board: list
    image_raw: list


def calibration_films(posterior: Posterior, films: int, folder: str | os.PathLike, *, n_dots: int = 150,
                      workers: int | None = None, scheduler=None, samples: int = 2000, progress: bool = False,
                      start: int = 0) -> list[CalibrationFilm]:
    """Simulate held-out films ``start`` to ``start + films - 1`` (kept in ``folder``), draw and measure their
    micrographs, and take the posterior's 90 % intervals from each micrograph and each board. A film that did not
    finish, or whose micrograph `measure_image` refuses, is left out (the list is shorter)."""
    points = [prior_point(k, "calibration", n_dots) for k in range(start, start + films)]
    rows = run_points(points, folder, workers=workers, scheduler=scheduler, state=True, progress=progress)
    out = []
    with tempfile.TemporaryDirectory() as scratch:
        for k, (point, row) in enumerate(zip(points, rows)):
            if row["status"] != "ok":
                continue
            state = checkpoint.read_state(Path(folder) / row["state_file"])
            board_x = observation(film_measures(state), {"sigma": row["film_sigma"],
                                                          "coverage": row["film_coverage"]})
            path = write_png(board_micrograph(state, seed=k), Path(scratch) / f"film{k}.png")
            try:
                film = measure_image(path, lqe=False)
            except InputError:  # refused as a user's image would be (a wide spread can look like a drawing): left out
                continue
            image_x = observation(image_measures(film), {"sigma": film.summary["size_spread"],
                                                         "coverage": film.summary["coverage"]})
            raw = posterior.sample(image_x, samples, k, calibrated=False)
            out.append(CalibrationFilm(point, credible_intervals(posterior.calibrate(raw)),
                                       credible_intervals(posterior.sample(board_x, samples, k)),
                                       credible_intervals(raw)))
    return out


def coverage_table(films: list[CalibrationFilm]) -> list[dict]:
    """Per parameter and per source (``image``, ``board``, ``image_raw``): the share of films whose 90 % interval
    holds the truth (``coverage_<source>``), its binomial standard error (``coverage_<source>_se``) and the
    intervals' mean width as a share of the prior (``width_<source>``)."""
    table = []
    for k, p in enumerate(PARAMETERS):
        row = {"parameter": p.key, "label": p.label, "films": len(films)}
        for source in ("image", "board", "image_raw"):
            intervals = [getattr(f, source)[k] for f in films]
            hits = [i["low"] <= f.point[p.key] <= i["high"] for i, f in zip(intervals, films)]
            share = float(np.mean(hits)) if hits else math.nan
            row[f"coverage_{source}"] = share
            row[f"coverage_{source}_se"] = math.sqrt(share * (1 - share) / max(len(hits), 1))
            row[f"width_{source}"] = float(np.mean([i["width_share"] for i in intervals])) if films else math.nan
        table.append(row)
    return table


def truths(films: list[CalibrationFilm]) -> np.ndarray:
    """The true parameters of the films, (films, 4)."""
    return np.array([[f.point[key] for key in parameter_keys()] for f in films], dtype=float).reshape(-1, 4)
