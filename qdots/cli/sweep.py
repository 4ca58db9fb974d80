"""Sweeps of qdots experiments: a base scene, axes over its keys, seeds; one packing row per run.

A sweep file for thesis Fig 2-4 (free films and gratings, four size spreads, four seeds)::

    base = "fig2-2a_sigma0.toml"          # from `qdots preset fig2-2 --save .`
    seeds = [154, 155, 156, 157]

    [axes]
    "deposition.sigma" = [0.0, 0.05, 0.10, 0.15]

    [[points]]
    label = "free"
    [[points]]
    label = "grating"
    grating = 77.94228634059948
    deposition.n_dots = 150
    deposition.mass_model = "volume"

    [output]
    dir = "fig2-4"
    state = true                          # keep each final board (.npz, resumable)

then ``qdots sweep fig2-4.toml`` and ``qdots sweep-plot fig2-4/table.csv
--metric interior_fraction --x deposition.sigma --group label``.

Every run's parameters are checked like a experiment file (an unknown key is an
error naming it, e.g. ``deposition.sigmaa``) before anything runs, and
completed with every default, so a run's hash covers the whole experiment.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from labrig.sweeps import load_sweep_file
from labrig.sweeps.files import SweepFile
from labrig.validate import InputError

from ..experiment import Experiment, run_experiment
from ..io.experiment_file import TABLES, experiment_from_dict, table_params

#: Wall seconds per time step and per dot and time step of a run, at the default engine settings (from fig2-2:
#: 160,000 steps, 3.0e7 dot-steps, 34 s), for `ExperimentRunner.estimate`.
STEP_SECONDS = 3e-5
DOT_STEP_SECONDS = 1e-6


def experiment_to_dict(exp: Experiment) -> dict:
    """Every parameter of ``exp`` as nested plain data (the experiment file's tables; unset values left out).

    ``experiment_from_dict(experiment_to_dict(exp)) == exp``.
    """
    def plain(value):
        return list(value) if isinstance(value, tuple) else value

    data = {key: getattr(exp, key) for key in Experiment.PARAMS}
    for name in TABLES:
        table = getattr(exp, name)
        data[name] = {key: plain(getattr(table, key)) for key in table_params(table) if getattr(table, key) is not None}
    data["forces"] = [{key: plain(value) for key, value in spec.items() if value is not None} for spec in exp.forces]
    return data


@dataclass(frozen=True)
class ExperimentRunner:
    """Runs one `Experiment` per parameter set; its row is `qdots.analysis.packing_summary` of the board.

    Parameters
    ----------
    quick : float, optional
        Scale every run down with `Experiment.quick` (in (0, 1]); the scaled
        experiment is what is hashed and recorded, so quick and full runs never mix.
    rule : {"text", "code"}
        Neighbour rule of the packing summary.
    """

    quick: float | None = None
    rule: str = "text"
    kind = "qdots.experiment"
    state_suffix = ".npz"

    def __post_init__(self) -> None:
        from ..analysis.packing import RULES

        if self.quick is not None and not (isinstance(self.quick, (int, float)) and 0 < self.quick <= 1):
            raise InputError(f"quick must be in (0, 1], got {self.quick!r}")
        if self.rule not in RULES:
            raise InputError(f"rule must be one of {RULES}, got {self.rule!r}")

    def canonical(self, params: dict) -> dict:
        """The full parameters of the experiment ``params`` describes (ValueError naming a bad key)."""
        exp = experiment_from_dict(params)
        return experiment_to_dict(exp if self.quick is None else exp.quick(self.quick))

    def estimate(self, params: dict) -> float:
        """About how many wall seconds the run of ``params`` takes on one core: `STEP_SECONDS` per time step
        plus `DOT_STEP_SECONDS` per dot and step, the dots arriving one by one (fig2-2, 300 dots and 400 s,
        took 34 s on one of 2 cores; the scenes that differ most from it may take 2-3x more or less)."""
        exp = experiment_from_dict(params)
        dep = exp.deposition
        n = dep.n_dots
        dot_seconds = dep.interval * n * (n - 1) / 2 + n * dep.settle
        return ((n * dep.interval + dep.settle) * STEP_SECONDS + dot_seconds * DOT_STEP_SECONDS) / exp.engine.dt

    def __call__(self, params: dict, state_path: Path | None = None) -> dict:
        from ..analysis.packing import packing_summary
        from ..io import checkpoint
        from .commands import OVERLAP_COLUMN

        sim = run_experiment(experiment_from_dict(params))
        state = sim.state()
        row = {**packing_summary(state, self.rule), "time_s": state.time, "steps": sim.steps_taken}
        row[OVERLAP_COLUMN] = 100 * row.pop("max_overlap")  # percent of a radius, as in summary.csv
        if state_path is not None:
            checkpoint.save(sim, state_path)
        return row


def load_sweep(path: str | os.PathLike) -> SweepFile:
    """Read a qdots sweep file (`labrig.sweeps.files`); its seeds go to the experiment's ``seed``."""
    return load_sweep_file(path, seed_key="seed")
