"""``qdots infer``: from a micrograph to the deposition conditions that made it, with credible intervals.

`infer_film` takes a measured film (`qdots.micrograph.measure.measure_image`), reads its size spread and
coverage (the conditions) and its measures (`qdots.inference.forward.film_measures`), brings the library of
simulated films up to the size asked (`qdots.inference.library.build_library`: only missing films run),
trains the amortized posterior on it or loads the one trained before (`qdots.inference.posterior`), and
draws the posterior of the four continuous parameters at the film's measures, and gives the probability of each
mass model (`qdots.inference.modelchoice`). Then the posterior-predictive check:
films simulated at parameters and mass models drawn from the posterior, at the film's size spread and coverage, measured
as the film was; each measure of the image is set against their spread (does the image fall inside the
films the posterior predicts?), and the film among them closest to the image is the best-fitting film.
It returns an `Inference` and writes nothing (`qdots.cli.files.infer` writes ``qdots infer``'s
files; `qdots.inference.plots` draws them).
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from labrig.validate import count

from ..io import checkpoint
from ..micrograph.choices import CHECK_FILMS, MAX_CHECK_FILMS, SAMPLES
from ..micrograph.measure import MeasuredFilm, measure_image
from .conformal import IntervalCalibration, describe_factor
from .forward import (
    FILM_DOTS,
    MASS_KEY,
    MASS_MODELS,
    MEASURES,
    PARAMETERS,
    SUMMARIES,
    image_measures,
    image_parts,
    image_point,
    parameter_keys,
)
from .library import LIBRARY_FILMS, build_library, observation, replicate_groups, shipped_replicates
from .posterior import ENSEMBLE, LEVEL, credible_intervals, load_or_train, require_sbi


@dataclass(frozen=True)
class Inference:
    """What `infer_film` found.

    Attributes
    ----------
    film : MeasuredFilm
        The (first) picture.
    conditions : dict
        The film's ``sigma`` and ``coverage`` (the simulations are built to match them; of several pictures, their
        mean weighted by their measured dots).
    measures : dict
        The film's measures (`qdots.inference.forward.MEASURES`; of several pictures, weighted as the conditions).
    samples : ndarray (n, 4)
        Posterior draws of the parameters (`qdots.inference.forward.PARAMETERS` order), spread by the calibration.
    intervals : list of dict
        Per parameter: median and the central 90 % credible interval (`credible_intervals`) of those draws, and
        ``calibration_spread``, the factor the networks' interval was spread by.
    calibration : IntervalCalibration
        How much the networks' intervals were spread to hold the truth in 90 % of held-out library films
        (`qdots.inference.conformal`).
    mass_models : list of dict
        Per mass model (`qdots.inference.forward.MASS_MODELS`): ``key``, ``label``, ``exponent`` and its posterior
        ``probability`` (equal prior probabilities; calibrated on the library's films kept out).
    check : list of dict
        The predictive check, one row per measure: ``measure``, ``label``, ``image``, ``median``, ``low``,
        ``high`` (5 % and 95 % of the predicted films), ``quantile`` (share of predicted films below the image),
        ``inside`` (the image within the 90 % band), ``used`` (a measure the posterior is conditioned on).
    predictive : list of dict
        The predicted films' rows (parameters, measures, ``state_file``).
    best : dict
        The predicted film closest to the image (its row), and ``state``: its board.
    library : Path
    films : int
        Training films the networks learnt from (the library's films less those kept for calibration).
    pictures, observations, dots : int
        The pictures of the sample, the independent observations they gave (parts of about a library film's dots:
        `qdots.inference.forward.image_parts`) and the measured dots behind them.
    effective_draws : float
        Of a joint posterior (several observations, `qdots.inference.posterior.joint_draws`), the effective number of
        proposals its draws were resampled from; of one observation, the draws.
    calibrated_as : str
        How the intervals and the mass models' probabilities were calibrated, in words (`joint_note`).
    timings : dict
        Wall seconds: ``measure``, ``library`` (films run for it), ``train`` (0 when loaded), ``sample``,
        ``check``, and ``library_films_run``, ``library_films_failed`` (left out of the training: over their wall-time
        budget, or a summary not measured), ``posterior_loaded``.
    """

    film: MeasuredFilm
    conditions: dict
    measures: dict
    samples: np.ndarray
    intervals: list
    calibration: IntervalCalibration
    mass_models: list
    check: list
    predictive: list
    best: dict
    library: Path
    films: int
    timings: dict = field(default_factory=dict)
    pictures: int = 1
    observations: int = 1
    dots: int = 0
    effective_draws: float = math.nan
    calibrated_as: str = ""


def predictive_points(samples: np.ndarray, conditions: dict, films: int, n_dots: int, seed: int = 0,
                      model_probabilities=None) -> list[dict]:
    """``films`` points for the predictive check: posterior draws spread over ``samples`` (every k-th), each with a
    mass model drawn from ``model_probabilities`` (default: equal), at the film's conditions, each with its own
    seed."""
    step = max(1, len(samples) // films)
    rng = np.random.default_rng([5603, seed])
    weights = np.full(len(MASS_MODELS), 1.0 / len(MASS_MODELS)) if model_probabilities is None else \
        np.asarray(model_probabilities, dtype=float) / np.sum(model_probabilities)
    out = []
    for row in samples[::step][:films]:
        point = {key: float(f"{v:.6g}") for key, v in zip(parameter_keys(), row)}
        point[MASS_KEY] = MASS_MODELS[int(rng.choice(len(MASS_MODELS), p=weights))].exponent
        point.update({k: float(f"{v:.6g}") for k, v in conditions.items()})
        point.update(n_dots=n_dots, seed=int(rng.integers(0, 2**31)))
        out.append(point)
    return out


def predictive_check(measures: dict, rows: list[dict], level: float = LEVEL) -> list[dict]:
    """One row per measure: the image's value against the predicted films' (see `Inference.check`)."""
    tail = 50.0 * (1.0 - level)
    table = []
    for key, label in MEASURES.items():
        values = np.array([row.get(key) for row in rows if row.get("status") == "ok" and row.get(key) is not None],
                          dtype=float)
        values = values[np.isfinite(values)]
        image = float(measures.get(key, math.nan))
        if values.size == 0:
            low = median = high = quantile = math.nan
        else:
            low, median, high = (float(v) for v in np.percentile(values, [tail, 50.0, 100.0 - tail]))
            quantile = float(np.mean(values < image) + 0.5 * np.mean(values == image))
        table.append({"measure": key, "label": label, "image": image, "median": median, "low": low, "high": high,
                      "quantile": quantile, "inside": bool(low <= image <= high), "used": key in SUMMARIES})
    return table


def closest_film(measures: dict, rows: list[dict]) -> dict:
    """The row among ``rows`` whose summaries are closest to ``measures``, each summary scaled by its spread
    over the rows (least squares)."""
    good = [row for row in rows if row.get("status") == "ok"]
    if not good:
        raise ValueError("no predicted film finished")
    values = np.array([[row.get(k) if row.get(k) is not None else np.nan for k in SUMMARIES] for row in good], float)
    target = np.array([measures[k] for k in SUMMARIES], dtype=float)
    scale = np.nanstd(values, axis=0)
    scale = np.where(scale > 0, scale, 1.0)
    distance = np.nansum(((values - target) / scale) ** 2, axis=1)
    return good[int(np.argmin(distance))]


def film_observations(films: list[MeasuredFilm], split: bool = True, dots: int = FILM_DOTS
                      ) -> tuple[np.ndarray, dict, dict, int]:
    """What the posterior is conditioned on, from one or more pictures of one sample: one observation per picture,
    or (``split``) per part of about ``dots`` measured dots (`qdots.inference.forward.image_parts`), each with its
    picture's size spread and coverage. Returns the observations (m, K), the pictures' measures and conditions
    pooled (weighted by their measured dots: what the predictive check sets against its films), and the measured
    dots behind them. `InputError` (one line) for a picture outside the trained conditions or with nothing to
    measure."""
    observations, weights, pooled, conditions = [], [], [], []
    for film in films:
        point = image_point(film)
        parts = image_parts(film, dots) if split else [np.asarray(film.complete, dtype=bool)]
        observations += [observation(image_measures(film, part), point) for part in parts]
        weights.append(int(np.count_nonzero(film.complete)))
        pooled.append(image_measures(film))
        conditions.append(point)
    w = np.asarray(weights, dtype=float) / max(1, sum(weights))
    measures = {key: float(np.sum([wk * m[key] for wk, m in zip(w, pooled)])) for key in pooled[0]}
    point = {key: float(np.sum([wk * c[key] for wk, c in zip(w, conditions)])) for key in conditions[0]}
    return np.asarray(observations, dtype=float), measures, point, int(sum(weights))


def infer_film(film: MeasuredFilm | list, library: str | os.PathLike, *, films: int = LIBRARY_FILMS,
               samples: int = SAMPLES, check_films: int = CHECK_FILMS, workers: int | None = None, scheduler=None,
               progress: bool = False, ensemble: int = ENSEMBLE, seed: int = 0, n_dots: int = FILM_DOTS,
               split: bool = True) -> Inference:
    """The posterior of the deposition parameters of a measured film (see the module).

    Parameters
    ----------
    film : MeasuredFilm or list of MeasuredFilm
        The film, or several pictures of one sample (independent observations of the same deposition).
    library : path
        The library folder (`qdots.inference.library`); created and filled when new.
    films : int
        Training films the posterior learns from (the library runs those it lacks; the films shipped with the
        package are not run).
    samples : int
        Posterior draws.
    check_films : int
        Films of the predictive check, in [1, `MAX_CHECK_FILMS`].
    workers, scheduler
        Where films run: local processes (default every core) or a Dask cluster (`labrig.sweeps.run_sweep`).
    progress : bool
        Say what runs, with a progress bar and its ETA.
    ensemble, seed
        Networks of the posterior and the seed of its training and draws.
    n_dots : int
        Dots of each simulated film (a library holds one size).
    split : bool
        Cut a picture of many dots into parts of about ``n_dots`` measured dots, each an observation
        (`qdots.inference.forward.image_parts`): the posterior then narrows with the dots in view. False: one
        observation per picture, as a film of ``n_dots`` would give.
    """
    check_films = count("check_films", check_films, 1, MAX_CHECK_FILMS)
    require_sbi()  # before any film is simulated
    pictures = list(film) if isinstance(film, (list, tuple)) else [film]
    if not pictures:
        raise ValueError("infer_film needs at least one measured film")
    observations, measures, conditions, dots = film_observations(pictures, split, n_dots)
    times = {}
    start = time.perf_counter()
    training = build_library(library, films, workers=workers, scheduler=scheduler, progress=progress, n_dots=n_dots)
    times["library"] = time.perf_counter() - start
    start = time.perf_counter()
    posterior, loaded = load_or_train(library, training.theta, training.models, training.x, training.ids,
                                      ensemble=ensemble, seed=seed,
                                      replicates=replicate_groups(shipped_replicates(n_dots)))
    times["train"] = 0.0 if loaded else time.perf_counter() - start
    start = time.perf_counter()
    draws, effective = posterior.sample_joint(observations, samples, seed)
    chance = posterior.model_probabilities(observations)
    times["sample"] = time.perf_counter() - start
    start = time.perf_counter()
    points = predictive_points(draws, conditions, check_films, n_dots, seed, chance)
    rows = build_checks(points, library, workers=workers, scheduler=scheduler, progress=progress)
    best = dict(closest_film(measures, rows))
    best["state"] = checkpoint.read_state(Path(library) / "checks" / best["state_file"])
    times["check"] = time.perf_counter() - start
    times.update(library_films_run=training.ran, library_films_failed=training.failed, posterior_loaded=loaded)
    intervals = [dict(row, calibration_spread=float(f)) for row, f in
                 zip(credible_intervals(draws, LEVEL), posterior.factors(len(observations)))]
    models = [{"key": m.key, "label": m.label, "exponent": m.exponent, "probability": float(p)}
              for m, p in zip(MASS_MODELS, chance)]
    return Inference(pictures[0], conditions, measures, draws, intervals, posterior.calibration, models,
                     predictive_check(measures, rows), rows, best, Path(library), posterior.training_films, times,
                     pictures=len(pictures), observations=len(observations), dots=dots,
                     effective_draws=effective, calibrated_as=joint_note(posterior, len(observations)))


def joint_note(posterior, observations: int) -> str:
    """How a posterior of ``observations`` observations is calibrated, in words."""
    if observations == 1:
        return "one observation: calibrated on the library's films kept out of the training"
    if posterior.joint is None:
        return (f"{observations} observations: NOT calibrated for several (no replicate films for this film size): "
                "the single observation's factors, which leave the intervals too narrow")
    _, _, count = posterior.joint.at(observations)
    extra = "" if count == observations else (
        f", fitted for {count}, the nearest count below" + ("; more observations than any set held: an "
                                                           "extrapolation" if observations > count else ""))
    return (f"{observations} observations: calibrated on {posterior.joint.groups} sets of replicate films" + extra)


def build_checks(points: list[dict], library: str | os.PathLike, **where) -> list[dict]:
    """Run the predictive films (kept with their boards in ``library/checks``); their rows."""
    from .library import run_points

    return run_points(points, Path(library) / "checks", state=True, **where)


def infer_image(path: str | os.PathLike | list, library: str | os.PathLike, *, nm_per_px=None,
                scale_bar: str | None = None, polarity: str = "auto", profile: str = "auto", page: int = 0,
                **options) -> Inference:
    """`measure_image` (without the film LQE) of one picture, or of each of a list of pictures of one sample (same
    scale options), then `infer_film` (``options`` are its keywords)."""
    require_sbi()  # before the picture is measured
    start = time.perf_counter()
    paths = list(path) if isinstance(path, (list, tuple)) else [path]
    films = [measure_image(p, nm_per_px=nm_per_px, scale_bar=scale_bar, polarity=polarity, profile=profile,
                           page=page, lqe=False) for p in paths]
    measured = time.perf_counter() - start
    result = infer_film(films if len(films) > 1 else films[0], library, **options)
    result.timings["measure"] = measured
    return result


def interval_rows(inference: Inference) -> list[tuple[str, str]]:
    """(label, text) rows of the credible intervals, for `labrig.cli.print_table`."""
    rows = []
    for row, p in zip(inference.intervals, PARAMETERS):
        rows.append((p.label, f"{row['median']:.3g}   90 % interval [{row['low']:.3g}, {row['high']:.3g}]   "
                              f"({100 * row['width_share']:.0f} % of the prior's [{p.low:g}, {p.high:g}]; "
                              f"the networks' interval spread {describe_factor(row['calibration_spread'])})"
                              + (" reaching the prior's bound" if row.get("at_bound") else "")))
    for model in inference.mass_models:
        rows.append((model["label"], f"probability {model['probability']:.2f}   (prior {1 / len(MASS_MODELS):.2f})"))
    rows.append(("calibration", inference.calibrated_as))
    return rows


def check_rows(inference: Inference) -> list[tuple[str, str]]:
    """(label, text) rows of the predictive check."""
    rows = []
    for row in inference.check:
        mark = "inside" if row["inside"] else "OUTSIDE"
        rows.append((row["label"] + (" *" if row["used"] else ""),
                     f"image {row['image']:.3g}   predicted {row['median']:.3g} [{row['low']:.3g}, {row['high']:.3g}]"
                     f"   {mark} (quantile {row['quantile']:.2f})"))
    return rows
