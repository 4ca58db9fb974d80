"""The library of simulated films of ``qdots infer``: a folder of films keyed by their parameters, kept and reused.

Layout of a library folder::

    LIBRARY/training/     films drawn from the prior: a `labrig.sweeps` output (runs/<id>.json, one record per
                          film keyed by the hash of its point; table.csv, one row per film)
    LIBRARY/checks/       films drawn from posteriors (the predictive checks), with their final boards (states/)
    LIBRARY/posteriors/   trained posteriors, each keyed by the films it learnt from (`qdots.inference.posterior`)

The training films are the points ``0, 1, 2, ...`` of one fixed stream of prior draws (`prior_point`): the
same index always gives the same point, so a library of 1,000 films asked for 1,500 runs the 500 new ones
only, and a second image (any size spread and coverage in `CONDITIONS`' ranges, which the draws cover)
reuses all of them. Films run through `labrig.sweeps.run_sweep`: a local process pool or a Dask cluster,
one progress bar with its ETA, resumable after a kill (finished films are on disk).
"""

from __future__ import annotations

import json
import math
import os
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from labrig.files import write_text_atomic
from labrig.sweeps import Sweep, run_sweep
from labrig.validate import InputError, count

from ..micrograph.choices import LIBRARY_FILMS, MAX_LIBRARY_FILMS
from .forward import CONDITIONS, FILM_DOTS, PARAMETERS, SUMMARIES, FilmRunner, condition_keys, parameter_keys

#: Roots of the random streams of prior draws: the training films, and the held-out films of the calibration.
STREAMS = {"training": 5601, "calibration": 5602}
#: Films that fail are replaced by further prior draws, up to this many times the films asked for.
MAX_REPLACED = 1


def prior_point(index: int, stream: str = "training", n_dots: int = FILM_DOTS) -> dict:
    """The ``index``-th point of the prior draws of ``stream``: every parameter and condition uniform between
    its bounds, and the film's seed, all from ``numpy.random.default_rng([STREAMS[stream], index])``."""
    if stream not in STREAMS:
        raise InputError(f"stream must be one of {', '.join(STREAMS)}, got {stream!r}")
    rng = np.random.default_rng([STREAMS[stream], count("index", index, 0, 2**62)])
    axes = (*PARAMETERS, *CONDITIONS)
    values = rng.uniform([a.low for a in axes], [a.high for a in axes])
    point = {a.key: float(f"{v:.6g}") for a, v in zip(axes, values)}
    point.update(n_dots=n_dots, seed=int(rng.integers(0, 2**31)))
    return point


def run_points(points: list[dict], folder: str | os.PathLike, *, workers: int | None = None, scheduler=None,
               state: bool = False, progress: bool = True) -> list[dict]:
    """Simulate and measure every point not yet in ``folder`` (a sweep output); returns one row per point
    (`labrig.sweeps` table rows: ``status``, the measures of `qdots.inference.forward.film_measures`, ``wall_s``,
    the point's keys, ``state_file`` when ``state``)."""
    if not points:
        return []
    sweep = Sweep(base=dict(points[0]), points=tuple(dict(p) for p in points))
    # retries=0: a film is deterministic, so a film that failed (one over its wall-time budget) would fail again
    result = run_sweep(sweep, FilmRunner(), folder, workers=workers, scheduler=scheduler, state=state, retries=0,
                       progress=progress, max_runs=len(points))
    return result.rows


@dataclass(frozen=True)
class Library:
    """The training films of a library folder, as arrays.

    Attributes
    ----------
    folder : Path
    rows : list of dict
        The films' table rows, in the order of the prior draws.
    theta : ndarray (N, 4)
        The parameters of each film that finished with every summary measured (`PARAMETERS` order).
    x : ndarray (N, 8)
        Its summaries (`SUMMARIES`) then its conditions (`CONDITIONS`): what the posterior is conditioned on.
    ids : list of str
        Those films' run ids (the key of a trained posterior).
    ran : int
        Films simulated by this call (0 when the library held them all).
    """

    folder: Path
    rows: list
    theta: np.ndarray
    x: np.ndarray
    ids: list
    ran: int

    @property
    def failed(self) -> int:
        """Films that did not finish or miss a summary (left out of the training)."""
        return len(self.rows) - len(self.ids)


def library_size(folder: str | os.PathLike) -> int:
    """Training films the library folder has asked for so far (0 for a new folder)."""
    path = Path(folder) / "library.json"
    try:
        return int(json.loads(path.read_text())["training_films"])
    except (OSError, ValueError, KeyError, TypeError):
        return 0


def build_library(folder: str | os.PathLike, films: int = LIBRARY_FILMS, *, workers: int | None = None,
                  scheduler=None, progress: bool = True, n_dots: int = FILM_DOTS) -> Library:
    """Bring the library in ``folder`` to at least ``films`` usable training films (running only the missing ones;
    films that fail or cannot be measured are replaced by further prior draws, at most `MAX_REPLACED` times
    ``films``) and return the first ``films`` usable ones as arrays.

    Parameters
    ----------
    folder : path
        The library folder (created if missing; see the module for its layout).
    films : int
        Training films wanted, in [1, `MAX_LIBRARY_FILMS`].
    workers, scheduler
        Where the films run (`labrig.sweeps.run_sweep`): local processes (default every core) or a Dask cluster.
    progress : bool
        Say what is about to run, and one progress bar with its ETA.
    n_dots : int
        Dots of each film (a library holds films of one size: another size is another library).
    """
    films = count("films", films, 1, MAX_LIBRARY_FILMS)
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    meta_path = folder / "library.json"
    if meta_path.is_file():
        meta = json.loads(meta_path.read_text())
        if meta.get("n_dots") != n_dots:
            raise InputError(f"library {str(folder)!r} holds films of {meta.get('n_dots')} dots, not {n_dots}: "
                             "use another folder for another film size")
    total = max(films, library_size(folder))
    before = _finished(folder / "training")
    while True:  # films that fail (an inelastic collapse, a film limit) are replaced by the next prior draws
        points = [prior_point(k, "training", n_dots) for k in range(total)]
        rows = run_points(points, folder / "training", workers=workers, scheduler=scheduler, progress=progress)
        write_text_atomic(meta_path, json.dumps({"format": "qdots-infer-library", "version": 1, "n_dots": n_dots,
                                                 "training_films": total,
                                                 "parameters": list(parameter_keys()),
                                                 "conditions": list(condition_keys()),
                                                 "summaries": list(SUMMARIES)}, indent=1))
        usable = [k for k, row in enumerate(rows) if usable_row(row)]
        missing = films - len(usable)
        if missing <= 0 or total >= min(MAX_LIBRARY_FILMS, films + MAX_REPLACED * films):
            break
        if progress:
            print(f"{missing} of the first {films} films were left out (failed or not measurable): running "
                  f"{missing} more to replace them", file=sys.stderr)
        total = min(MAX_LIBRARY_FILMS, total + missing)
    rows = rows[:usable[films - 1] + 1] if len(usable) >= films else rows  # up to the last film used
    theta, x, ids = training_arrays(rows)
    return Library(folder, rows, theta, x, ids, max(0, _finished(folder / "training") - before))


def _finished(sweep_folder: Path) -> int:
    runs = sweep_folder / "runs"
    return sum(1 for _ in runs.glob("*.json")) if runs.is_dir() else 0


def usable_row(row: dict) -> bool:
    """Whether a training film finished with every summary and condition measured (finite)."""
    if row.get("status") != "ok":
        return False
    values = [row.get(key) for key in SUMMARIES] + [row.get(f"film_{key}") for key in condition_keys()]
    return all(v is not None and math.isfinite(v) for v in values)


def training_arrays(rows: list[dict]) -> tuple[np.ndarray, np.ndarray, list]:
    """(theta, x, run ids) of the rows that finished with every summary finite; x holds each film's own size
    spread and coverage (``film_sigma``, ``film_coverage``), as a micrograph's are measured, not its point's."""
    theta, x, ids = [], [], []
    for row in rows:
        if not usable_row(row):
            continue
        summaries = [row[key] for key in SUMMARIES] + [row[f"film_{key}"] for key in condition_keys()]
        theta.append([row[key] for key in parameter_keys()])
        x.append(summaries)
        ids.append(row["run"])
    return (np.asarray(theta, dtype=float).reshape(-1, len(PARAMETERS)),
            np.asarray(x, dtype=float).reshape(-1, len(SUMMARIES) + len(CONDITIONS)), ids)


def observation(measures: dict, conditions: dict) -> np.ndarray:
    """The vector a posterior is conditioned on: the summaries of ``measures`` then the ``conditions``."""
    values = [measures[key] for key in SUMMARIES] + [conditions[key] for key in condition_keys()]
    bad = [key for key, v in zip([*SUMMARIES, *condition_keys()], values) if not math.isfinite(v)]
    if bad:
        raise InputError(f"the film's {bad[0]} could not be measured (too few dots with their whole "
                         "neighbourhood in the picture): nothing to infer from")
    return np.asarray(values, dtype=float)
