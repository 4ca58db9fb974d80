"""The library of simulated films of ``qdots infer``: a folder of films keyed by their parameters, kept and reused.

Layout of a library folder::

    LIBRARY/training/     films drawn from the prior: a `labrig.sweeps` output (runs/<id>.json, one record per
                          film keyed by the hash of its point; table.csv, one row per film)
    LIBRARY/checks/       films drawn from posteriors (the predictive checks), with their final boards (states/)
    LIBRARY/posteriors/   trained posteriors, each keyed by the films it learnt from (`qdots.inference.posterior`)

The training films are the points ``0, 1, 2, ...`` of one fixed stream of prior draws (`prior_point`): the
same index always gives the same point, so a library of 1,000 films asked for 1,500 runs the 500 new ones
only, and a second image (any size spread and coverage in `CONDITIONS`' ranges, which the draws cover)
reuses all of them. The first 3,000 training films of 150 dots, and 60 x 8 replicate films, are shipped with the
package (`SHIPPED`, `SHIPPED_REPLICATES`: simulated once per release by ``python -m benchmarks.qdots_infer --ship``,
and checked by a test against the current code), so a new library runs none of them. Films run through
`labrig.sweeps.run_sweep`: a local process pool or a Dask cluster, one progress bar with its ETA, resumable after a
kill (finished films are on disk).
"""

from __future__ import annotations

import csv
import gzip
import io
import json
import math
import os
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from labrig.files import atomic_path, write_text_atomic
from labrig.sweeps import Sweep, run_sweep
from labrig.validate import InputError, count

from ..micrograph.choices import LIBRARY_FILMS, MAX_LIBRARY_FILMS
from .forward import (
    CONDITIONS,
    FILM_DOTS,
    MASS_KEY,
    MASS_MODELS,
    MEASURES,
    PARAMETERS,
    SUMMARIES,
    FilmRunner,
    condition_keys,
    mass_model_index,
    parameter_keys,
)

#: Roots of the random streams of prior draws: the training films, and the held-out films of the calibration
#: (5601 and 5602 were those of the first prior, with a continuous mass exponent and no attraction).
STREAMS = {"training": 5611, "calibration": 5612, "replicates": 5613}
#: The version of a library folder's prior: a folder of another version holds films of another prior.
LIBRARY_VERSION = 2
#: The films shipped with the package (`shipped_rows`): the first films of the training stream, simulated once per
#: release (`write_shipped`), so that a first inference trains at once; keyed by the films' dots.
SHIPPED = {FILM_DOTS: Path(__file__).with_name("data") / f"library-v{LIBRARY_VERSION}-{FILM_DOTS}-dots.csv.gz"}
#: The replicate films shipped with it (`shipped_replicates`): `REPLICATE_GROUPS` depositions of the
#: ``"replicates"`` stream, `REPLICATE_COPIES` seeds each, which calibrate posteriors of several observations.
SHIPPED_REPLICATES = {FILM_DOTS: Path(__file__).with_name("data") /
                      f"library-v{LIBRARY_VERSION}-{FILM_DOTS}-dots-replicates.csv.gz"}
REPLICATE_GROUPS, REPLICATE_COPIES = 60, 8
#: The columns of a shipped film: its run id and status, its point, its measures, its wall time when simulated.
SHIPPED_COLUMNS = ("run", "status", *(p.key for p in PARAMETERS), MASS_KEY, *(c.key for c in CONDITIONS), "n_dots",
                   "seed", *MEASURES, "complete_dots", "film_sigma", "film_coverage", "wall_s", "group", "copy")
#: Films that fail are replaced by further prior draws, up to this many times the films asked for.
MAX_REPLACED = 1


def prior_point(index: int, stream: str = "training", n_dots: int = FILM_DOTS) -> dict:
    """The ``index``-th point of the prior draws of ``stream``: every continuous parameter and condition uniform
    between its bounds, one of the `MASS_MODELS` with equal probability, and the film's seed, all from
    ``numpy.random.default_rng([STREAMS[stream], index])``."""
    if stream not in STREAMS:
        raise InputError(f"stream must be one of {', '.join(STREAMS)}, got {stream!r}")
    rng = np.random.default_rng([STREAMS[stream], count("index", index, 0, 2**62)])
    axes = (*PARAMETERS, *CONDITIONS)
    values = rng.uniform([a.low for a in axes], [a.high for a in axes])
    point = {a.key: float(f"{v:.6g}") for a, v in zip(axes, values)}
    point[MASS_KEY] = MASS_MODELS[int(rng.integers(0, len(MASS_MODELS)))].exponent
    point.update(n_dots=n_dots, seed=int(rng.integers(0, 2**31)))
    return point


def replicate_points(group: int, copies: int, n_dots: int = FILM_DOTS) -> list[dict]:
    """``copies`` films of one deposition: the ``group``-th point of the ``"replicates"`` stream, each copy with its
    own seed (independent pictures of one sample: what calibrates a posterior of several observations)."""
    base = prior_point(group, "replicates", n_dots)
    rng = np.random.default_rng([STREAMS["replicates"], count("group", group, 0, 2**62), 1])
    return [dict(base, seed=int(rng.integers(0, 2**31))) for _ in range(count("copies", copies, 1, 1000))]


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
        The continuous parameters of each film that finished with every summary measured (`PARAMETERS` order).
    models : ndarray (N,) of int
        Each of those films' mass model (its index in `MASS_MODELS`).
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
    models: np.ndarray
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
        if meta.get("version") != LIBRARY_VERSION:
            raise InputError(f"library {str(folder)!r} holds films of another prior (version {meta.get('version')}, "
                             f"this qdots draws version {LIBRARY_VERSION}): use another folder")
        if meta.get("n_dots") != n_dots:
            raise InputError(f"library {str(folder)!r} holds films of {meta.get('n_dots')} dots, not {n_dots}: "
                             "use another folder for another film size")
    total = max(films, library_size(folder))
    before = _finished(folder / "training")
    shipped = shipped_rows(n_dots)
    while True:  # films that fail (an inelastic collapse, a film limit) are replaced by the next prior draws
        points = [prior_point(k, "training", n_dots) for k in range(total)]
        known = shipped[:total]  # the films shipped with the package are not run again
        rows = known + run_points(points[len(known):], folder / "training", workers=workers, scheduler=scheduler,
                                  progress=progress)
        write_text_atomic(meta_path, json.dumps({"format": "qdots-infer-library", "version": LIBRARY_VERSION, "n_dots": n_dots,
                                                 "training_films": total,
                                                 "parameters": list(parameter_keys()),
                                                 "mass_models": [m.key for m in MASS_MODELS],
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
    theta, models, x, ids = training_arrays(rows)
    return Library(folder, rows, theta, models, x, ids, max(0, _finished(folder / "training") - before))


def read_shipped(path: Path) -> list[dict]:
    """The rows of a shipped table (`write_shipped`), each value as it was written; [] when there is no file."""
    if not path.is_file():
        return []
    with gzip.open(path, "rt", newline="") as stream:
        table = list(csv.DictReader(stream))
    rows = []
    for raw in table:
        row: dict = {"run": raw["run"], "status": raw["status"]}
        for key in SHIPPED_COLUMNS[2:]:
            value = raw.get(key, "")
            row[key] = None if value in ("", None) else (int(value) if key in ("n_dots", "seed", "complete_dots", "group",
                                                                            "copy") else float(value))
        rows.append(row)
    return rows


def matches(row: dict, point: dict) -> bool:
    """Whether a shipped ``row`` is the film of ``point`` (every key of the point, the same value)."""
    return all(row.get(key) == value for key, value in point.items())


def shipped_rows(n_dots: int = FILM_DOTS) -> list[dict]:
    """The training films shipped with the package for films of ``n_dots`` dots (`SHIPPED`; none for another size):
    rows as `run_points` gives them, points ``0, 1, ...`` of the training stream. A shipped film whose point is
    not the current prior's draw (a prior changed without the file) ends the list there."""
    rows = []
    for k, row in enumerate(read_shipped(SHIPPED[n_dots]) if n_dots in SHIPPED else []):
        if not matches(row, prior_point(k, "training", n_dots)):
            break
        rows.append(row)
    return rows


def shipped_replicates(n_dots: int = FILM_DOTS) -> list[dict]:
    """The replicate films shipped for films of ``n_dots`` dots (`SHIPPED_REPLICATES`), each checked against its
    point (`replicate_points`); [] for another size or a table of another prior."""
    rows = read_shipped(SHIPPED_REPLICATES[n_dots]) if n_dots in SHIPPED_REPLICATES else []
    copies = max([row["copy"] for row in rows], default=-1) + 1
    expected = {g: replicate_points(g, copies, n_dots) for g in {row["group"] for row in rows}}
    return rows if all(matches(row, expected[row["group"]][row["copy"]]) for row in rows) else []


def replicate_groups(rows: list[dict]) -> list[tuple[np.ndarray, int, np.ndarray]]:
    """Replicate films as sets: per group, ``(theta, mass model index, observations (c, K))`` of its usable
    films (`qdots.inference.posterior.fit_joint_calibration`); groups with fewer than 2 usable films are left out."""
    by_group: dict[int, list[dict]] = {}
    for row in rows:
        if usable_row(row):
            by_group.setdefault(int(row["group"]), []).append(row)
    out = []
    for group in sorted(by_group):
        members = sorted(by_group[group], key=lambda r: r["copy"])
        if len(members) < 2:
            continue
        theta, models, x, _ = training_arrays(members)
        out.append((theta[0], int(models[0]), x))
    return out


def build_replicates(folder: str | os.PathLike, groups: int = REPLICATE_GROUPS, copies: int = REPLICATE_COPIES, *,
                     workers: int | None = None, scheduler=None, progress: bool = True, n_dots: int = FILM_DOTS,
                     first: int = 0) -> list[dict]:
    """Run the replicate films of ``groups`` depositions from the ``first``-th, ``copies`` seeds each
    (`replicate_points`), in ``folder`` (a sweep output); their rows, each with its ``group`` and ``copy``. The
    shipped sets are groups ``0 ..``; held-out sets that test them start further on."""
    points = [p for g in range(first, first + groups) for p in replicate_points(g, copies, n_dots)]
    rows = run_points(points, folder, workers=workers, scheduler=scheduler, progress=progress)
    return [dict(row, group=first + k // copies, copy=k % copies) for k, row in enumerate(rows)]


def write_shipped(rows: list[dict], path: str | os.PathLike) -> Path:
    """Write ``rows`` (training films, points ``0, 1, ...`` of the training stream, or replicate films with their
    ``group`` and ``copy``, as `run_points` and `build_replicates` give them) as a shipped table: gzip CSV of
    `SHIPPED_COLUMNS`, floats to the last bit, written atomically and byte-reproducibly. For a release:
    ``python -m benchmarks.qdots_infer --ship`` builds the films and writes both tables."""
    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=SHIPPED_COLUMNS, extrasaction="ignore", lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({key: ("" if row.get(key) is None else repr(row[key]) if isinstance(row[key], float)
                               else row[key]) for key in SHIPPED_COLUMNS})
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp, open(tmp, "wb") as raw:
        # no name and mtime 0 in the gzip header: the same films give the same bytes
        with gzip.GzipFile(filename="", mode="wb", fileobj=raw, mtime=0) as stream:
            stream.write(text.getvalue().encode())
    return path


def _finished(sweep_folder: Path) -> int:
    runs = sweep_folder / "runs"
    return sum(1 for _ in runs.glob("*.json")) if runs.is_dir() else 0


def usable_row(row: dict) -> bool:
    """Whether a training film finished with every summary and condition measured (finite)."""
    if row.get("status") != "ok":
        return False
    values = [row.get(key) for key in SUMMARIES] + [row.get(f"film_{key}") for key in condition_keys()]
    return all(v is not None and math.isfinite(v) for v in values)


def training_arrays(rows: list[dict]) -> tuple[np.ndarray, np.ndarray, np.ndarray, list]:
    """(theta, mass models, x, run ids) of the rows that finished with every summary finite; x holds each film's own
    size spread and coverage (``film_sigma``, ``film_coverage``), as a micrograph's are measured, not its point's."""
    theta, models, x, ids = [], [], [], []
    for row in rows:
        if not usable_row(row):
            continue
        summaries = [row[key] for key in SUMMARIES] + [row[f"film_{key}"] for key in condition_keys()]
        theta.append([row[key] for key in parameter_keys()])
        models.append(mass_model_index(row[MASS_KEY]))
        x.append(summaries)
        ids.append(row["run"])
    return (np.asarray(theta, dtype=float).reshape(-1, len(PARAMETERS)), np.asarray(models, dtype=int),
            np.asarray(x, dtype=float).reshape(-1, len(SUMMARIES) + len(CONDITIONS)), ids)


def observation(measures: dict, conditions: dict) -> np.ndarray:
    """The vector a posterior is conditioned on: the summaries of ``measures`` then the ``conditions``."""
    values = [measures[key] for key in SUMMARIES] + [conditions[key] for key in condition_keys()]
    bad = [key for key, v in zip([*SUMMARIES, *condition_keys()], values) if not math.isfinite(v)]
    if bad:
        raise InputError(f"the film's {bad[0]} could not be measured (too few dots with their whole "
                         "neighbourhood in the picture): nothing to infer from")
    return np.asarray(values, dtype=float)
