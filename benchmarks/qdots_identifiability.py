"""What a picture of a film can tell: the film measures against each deposition parameter, beside their seed spread.

Around the thesis's values (thermal kicks 1x the thesis's, equal masses, restitution 0.8, no drag) at the
shared micrograph's size spread (15 %) and coverage (0.336), each parameter of `qdots.inference.forward`
is moved one step (both ways where the prior allows) with the others held, and ``SEEDS`` films of 150
dots are run at every point (`qdots.inference.library.run_points`: the sweep machinery, 2 workers).
Every measure of `qdots.inference.forward.MEASURES` is tabulated as its change over the step in units of
its seed standard deviation (one film's spread: |z| < 1 means one picture cannot see the step), with the
standard error of that z from the seeds.

Then the Fisher information of one film about the four parameters, from the slopes of the `SUMMARIES`
the inference uses and their seed covariance (shrunk halfway to its diagonal, the seeds being few):
``F = J^T C^-1 J``. ``sqrt(diag(F^-1))`` is the smallest posterior standard deviation one film allows
for each parameter (the Cramér-Rao bound, linearised at the base point); a parameter whose bound is
not well below its prior's standard deviation cannot be pinned down by one picture. The eigenvectors of
``F`` with the smallest eigenvalues are the directions the picture cannot see.

Run: ``python -m benchmarks.qdots_identifiability [--quick]``
"""

from __future__ import annotations

import math
import tempfile
import time

import numpy as np

from qdots.inference.forward import CONDITIONS, MASS_KEY, MEASURES, PARAMETERS, SUMMARIES, Parameter
from qdots.inference.library import run_points

from .report import Headline, Note, Table, cli

#: The code this benchmark measures (besides itself): a commit to it after a run marks the run's section as
#: older than its code (`benchmarks.staleness`).
MEASURED_CODE = ("qdots/inference", "qdots/engine", "qdots/forces", "qdots/experiment.py", "qdots/deposition.py",
                 "qdots/analysis")

#: The base point: the thesis's values at the shared micrograph's size spread and coverage.
BASE = {"kick": 0.0, "mass_exponent": 0.0, "restitution": 0.8, "drag": -3.0, "attraction": 0.0, "sigma": 0.15,
        "coverage": 0.336}
#: The steps: (key, values tried besides the base).
STEPS = (("kick", (-0.3, 0.3)), ("mass_exponent", (3.0,)), ("restitution", (0.75, 0.85)), ("drag", (-1.0,)),
         ("attraction", (-0.3, 0.3)), ("sigma", (0.10, 0.20)), ("coverage", (0.28, 0.40)))
#: The axes of the Fisher analysis: the continuous parameters and the mass exponent, taken as continuous between the
#: mass models' 0 and 3 (locally: the step from equal masses to masses ~ d^3).
AXES = (*PARAMETERS, Parameter(MASS_KEY, "mass exponent p (m ~ d^p)", 0.0, 3.0, 0.0, "masses (d / mean d)^p"))
#: Films per point (full, quick).
SEEDS, QUICK_SEEDS = 16, 4


def points(seeds: int) -> list[dict]:
    """Every film of the study: the base and each step, ``seeds`` seeds each (seeds 1000, 1001, ...)."""
    out = []
    for key, value in [(None, None)] + [(key, v) for key, values in STEPS for v in values]:
        for s in range(seeds):
            point: dict = dict(BASE, n_dots=150, seed=1000 + s)
            if key is not None:
                point[key] = value
            out.append(point)
    return out


def measure_matrix(rows: list[dict]) -> np.ndarray:
    """The measures of `MEASURES` of each row, (rows, measures); NaN where one is missing."""
    return np.array([[np.nan if row.get(k) is None else float(row[k]) for k in MEASURES] for row in rows])


def sensitivity(rows: list[dict], seeds: int) -> dict:
    """Per step: the mean change of each measure, its z (change over the pooled seed SD) and that z's SE."""
    values = measure_matrix(rows)
    base = values[:seeds]
    out, k = {}, seeds
    for key, steps in STEPS:
        for v in steps:
            moved = values[k:k + seeds]
            k += seeds
            change = np.nanmean(moved, axis=0) - np.nanmean(base, axis=0)
            sd = np.sqrt(0.5 * (np.nanvar(moved, axis=0, ddof=1) + np.nanvar(base, axis=0, ddof=1)))
            with np.errstate(divide="ignore", invalid="ignore"):
                z = np.where(sd > 1e-9 * np.abs(np.nanmean(base, axis=0)), change / sd, np.nan)
            out[(key, v)] = {"change": change, "z": z, "z_se": math.sqrt(2.0 / seeds), "sd": sd,
                             "slope": change / (v - BASE[key])}
    return out


def fisher(rows: list[dict], seeds: int, effects: dict) -> tuple[np.ndarray, np.ndarray]:
    """The Fisher information of one film about the parameters (see the module) and the summaries' SDs."""
    names = list(MEASURES)
    use = [names.index(s) for s in SUMMARIES]
    base = measure_matrix(rows)[:seeds][:, use]
    cov = np.cov(base, rowvar=False)
    sd = np.sqrt(np.diag(cov))
    keep = sd > 0  # a summary that never moved between seeds carries no usable information here
    cov = 0.5 * cov + 0.5 * np.diag(np.diag(cov))
    jac = []
    for p in AXES:
        slopes = [effects[(p.key, v)]["slope"][use] for v in dict(STEPS)[p.key]]
        jac.append(np.mean(slopes, axis=0))
    jac = np.array(jac).T[keep]  # (summaries, parameters)
    return jac.T @ np.linalg.solve(cov[np.ix_(keep, keep)], jac), sd


def run(quick: bool) -> list:
    seeds = QUICK_SEEDS if quick else SEEDS
    todo = points(seeds)
    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as folder:
        rows = run_points(todo, folder, workers=2, progress=not quick)
    wall = time.perf_counter() - start
    failed = sum(row["status"] != "ok" for row in rows)
    effects = sensitivity(rows, seeds)
    columns = ["measure", "base mean +- seed SD"] + [f"{key} {BASE[key]:g} -> {v:g}" for key, vs in STEPS for v in vs]
    base = measure_matrix(rows)[:seeds]
    table = Table(f"Sensitivity of the film measures: change over the step in seed SDs (z; one film's SE of z "
                  f"{math.sqrt(2.0 / seeds):.2f}), {seeds} films of 150 dots per point", columns)
    for m, (key, label) in enumerate(MEASURES.items()):
        row = [label + (" *" if key in SUMMARIES else ""),
               f"{np.nanmean(base[:, m]):.3g} +- {np.nanstd(base[:, m], ddof=1):.2g}"]
        row += [f"{effects[(k, v)]['z'][m]:+.1f}" for k, vs in STEPS for v in vs]
        table.rows.append(row)
    table.note = ("* the measures the inference is conditioned on. Base: " + ", ".join(f"{k} {v:g}" for k, v in
                                                                                      BASE.items())
                  + f". {len(rows)} films, {failed} failed, {wall:.0f} s on 2 workers.")
    info, _ = fisher(rows, seeds, effects)
    bound = np.sqrt(np.diag(np.linalg.pinv(info)))
    prior_sd = np.array([(p.high - p.low) / math.sqrt(12.0) for p in AXES])
    ident = Table("What one film of 150 dots can pin down: the Cramér-Rao bound on each parameter against its "
                  "prior's SD (linearised at the base point)",
                  ["parameter", "prior range", "prior SD", "smallest posterior SD (one film)", "bound / prior SD",
                   "one picture"])
    for p, b, s in zip(AXES, bound, prior_sd):
        verdict = "identified" if b < 0.35 * s else ("weakly" if b < 0.8 * s else "not identified")
        ident.rows.append([p.label, f"[{p.low:g}, {p.high:g}]", f"{s:.3g}", f"{b:.3g}", f"{b / s:.2f}", verdict])
    scaled = info * np.outer(prior_sd, prior_sd)  # information in units of the prior's SDs
    eigenvalues, vectors = np.linalg.eigh(scaled)
    weak = ", ".join(f"{value:.3g} along ({', '.join(f'{c:+.2f} {p.key}' for c, p in zip(vectors[:, k], AXES))})"
                     for k, value in enumerate(eigenvalues[:2]))
    note = Note(f"Eigenvalues of one film's Fisher information in prior-SD units: "
                f"{', '.join(f'{v:.3g}' for v in eigenvalues)}; the two weakest directions: {weak}. An eigenvalue "
                "below 1 is a direction one picture tells less about than the prior already does. The conditions "
                f"({', '.join(c.key for c in CONDITIONS)}) move the measures as much as the parameters do, which "
                "is why the inference takes them from the micrograph.")
    head = Headline("qdots infer: identifiability (sensitivity of the film measures, Fisher bound)",
                    f"{wall / len(rows):.2f} s per film (2 workers)",
                    ", ".join(f"{p.key} {b / s:.2f}" for p, b, s in zip(AXES, bound, prior_sd))
                    + " (bound / prior SD)")
    return [head, table, ident, note]


def main(argv: list[str] | None = None) -> int:
    return cli(run, __doc__.splitlines()[0], argv)


if __name__ == "__main__":
    raise SystemExit(main())
