"""The qdots films behind Fig 2-2 to 2-6 and Table 2.1: one resumable sweep.

Every packing figure of chapter 2 reads the same boards, so they are run once, as one
`labrig.sweeps.Sweep` whose runs are identified by their full parameters: an interrupted
``python -m reproduce`` resumes where it stopped, and a figure added later reuses the runs.

=====================  =========================================================================
family                 runs (each at every seed)
=====================  =========================================================================
``free``               the ``fig2-2`` preset: 300 dots, 600 x 600 px, equal masses, sigma 0,
                       0.05, 0.10, 0.15 (Fig 2-2, 2-4, 2-5, the equal curve of 2-6a)
``grating``            the ``fig2-3`` preset: 150 dots in a channel 6 lattice spacings wide,
                       masses ~ d^3, the same sigmas (Fig 2-3, 2-4)
``free, mass ~ d^3``   as ``free`` with masses ~ d^3 (the Java's ``relativeMasses``), sigma 0.05,
                       0.10, 0.15 (Fig 2-6a; at sigma 0 every dot has the mean mass in both
                       models, so that point is the ``free`` runs)
``bimodal``            uniform size, half the dots twice as heavy (Fig 2-6b, Table 2.1)
=====================  =========================================================================
"""

from __future__ import annotations

from pathlib import Path

from labrig.sweeps import Sweep, run_sweep
from qdots.cli.sweep import ExperimentRunner, experiment_to_dict
from qdots.io.checkpoint import read_state
from qdots.presets import GRATING_WIDTH, PRESETS

#: Size spreads of Fig 2-4 and 2-6a (standard deviation of the diameter over its mean).
SIGMAS = (0.0, 0.05, 0.10, 0.15)
#: Each family: the dotted keys it changes from the ``fig2-2`` preset.
FAMILIES = {
    "free": {},
    "grating": {"grating": GRATING_WIDTH, "deposition.n_dots": 150, "deposition.mass_model": "volume"},
    "bimodal": {"deposition.mass_model": "bimodal", "deposition.heavy_mass": 2.0},
    "free, mass ~ d^3": {"deposition.mass_model": "volume"},
}
#: What joins a family and its sigma in a point's label (labels are unique).
LABEL_SIGMA = ", sigma "
#: Sigmas run for each family.
FAMILY_SIGMAS = {"free": SIGMAS, "grating": SIGMAS, "bimodal": (0.0,), "free, mass ~ d^3": SIGMAS[1:]}


def film_sweep(seeds: int, engine: str = "chipmunk") -> Sweep:
    """Every film of chapter 2 at ``seeds`` seeds (154, 155, ...: the Java's seed first), run by ``engine``
    (`qdots.engine.ENGINES`)."""
    labels = {(family, sigma): f"{family}{LABEL_SIGMA}{sigma:g}"
              for family in FAMILIES for sigma in FAMILY_SIGMAS[family]}
    points = [{"label": label, "name": label, **FAMILIES[family], "deposition.sigma": sigma}
              for (family, sigma), label in labels.items()]
    base = experiment_to_dict(PRESETS["fig2-2"][0])
    base["engine"] = {**base.get("engine", {}), "kind": engine}
    return Sweep(base=base, points=points, seeds=seeds)


def run_films(out: Path, *, seeds: int, quick: float | None, workers: int, engine: str = "chipmunk",
              progress: bool = True) -> dict:
    """Run (or resume) the film sweep in ``out``; its boards by ``(family, sigma, seed)``.

    Parameters
    ----------
    out : Path
        Sweep directory (run records, final states, table); kept between calls.
    seeds : int
        Seeds per point (>= 1).
    engine : str
        The engine that runs the films (`qdots.engine.ENGINES`).
    quick : float or None
        Scale every experiment with `qdots.Experiment.quick` (None: full size).
    workers : int
        Runs at a time.
    progress : bool
        A progress bar over the runs.

    Returns
    -------
    dict
        ``{"boards": {(family, sigma, seed): State}, "rows": table rows, "wall_s": summed run time}``.
    """
    result = run_sweep(film_sweep(seeds, engine), ExperimentRunner(quick=quick), out, workers=workers, state=True,
                       progress=progress)
    failed = [row["error"] for row in result.rows if row["status"] != "ok"]
    if failed:
        raise RuntimeError(f"{len(failed)} film run(s) failed, first: {failed[0]}")
    boards = {}
    for row in result.rows:
        row["family"] = row["label"].rsplit(LABEL_SIGMA, 1)[0]
        key = (row["family"], row["deposition.sigma"], row["seed"])
        boards[key] = read_state(result.table.parent / row["state_file"])
    return {"boards": boards, "rows": result.rows, "wall_s": sum(row["wall_s"] or 0.0 for row in result.rows)}
