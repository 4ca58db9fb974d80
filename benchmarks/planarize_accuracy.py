"""planarize speed against error: grid, step, batch tolerance and distance kind against converged answers.

Two cases, each run at its default settings and with one knob changed at a time:

* ``hill``: the thesis hill to 1 nm (default: refined 4x = 17 x 17, step 0.01 nm);
* ``ta``: a 200 nm patch of the thesis's Ta roughness to 40 nm (default: refined 4x = 41 x 41 at
  5 nm, step 0.5 nm);

both at k_exp 2.3, fast engine, default batch tolerance (a tenth of a step), thesis distances.
The error of a setting is the largest relative difference of its metal and oxide RMS from the
converged answer's, at ten evenly spaced oxide thicknesses (each interpolated in its history).
The converged answer is the same surface on a grid 4x finer than the default with a 4x smaller
step (hill), resp. 2x both (Ta), at a quarter-step tolerance. For the batch tolerance the table
also gives the difference from tolerance 0, which reproduces the thesis's sequential algorithm
bit for bit: the fast engine's own error, free of the discretization's. Time is wall time.

Run: ``python -m benchmarks.planarize_accuracy [--quick]``
"""

from __future__ import annotations

import time

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure as MplFigure

from planarize import Fast, Model, anodize, surfaces
from planarize.metrics import history_difference

from . import pareto
from .report import Figure, Headline, Note, Table, cli

#: The code this benchmark measures (besides itself): a commit to it after a run marks the run's section as
#: older than its code (`benchmarks.staleness`).
MEASURED_CODE = ("planarize",)

K_EXP = 2.3


def surface(case: str, refine: int):
    if case == "hill":
        return surfaces.hill(refine=refine)
    return surfaces.random_roughness(size=200.0, seed=1, refine=refine)


#: case -> (thickness nm, default step nm, default refinement, converged (refine, step))
CASES = {"hill": (1.0, 0.01, 4, (16, 0.0025)), "ta": (40.0, 0.5, 4, (8, 0.25))}
QUICK_CASES = {"hill": (0.5, 0.01, 4, (8, 0.005))}


def run_once(case: str, thickness: float, refine: int, step: float, tolerance: float | None = None,
             distance: str = "thesis"):
    s = surface(case, refine)
    start = time.perf_counter()
    run = anodize(s, thickness, record=200, model=Model(step=step, k_exp=K_EXP, distance=distance), engine=Fast(tolerance=tolerance))
    return run, time.perf_counter() - start


def rms_error(run, ref, thickness: float) -> float:
    return history_difference(run, ref, np.linspace(thickness / 10, thickness, 10))


def knobs(step: float, refine: int, quick: bool) -> dict:
    """knob -> list of (label, keyword changes, is default)."""
    grid = (2, 4) if quick else (2, 4, 8)
    steps = (2.0, 1.0) if quick else (4.0, 2.0, 1.0, 0.5)
    tolerances = (0.0, 0.1, 0.5) if quick else (0.0, 0.1, 0.25, 0.5, 1.0, 2.0)
    return {
        "grid refinement": [(f"{g}x", {"refine": g}, g == refine) for g in grid],
        "step": [(f"{f * step:g} nm", {"step": f * step}, f == 1.0) for f in steps],
        "batch tolerance": [(f"{t:g} step", {"tolerance": t * step}, t == 0.1) for t in tolerances],
        "distance kind": [(d, {"distance": d}, d == "thesis") for d in ("thesis", "exact")],
    }


def study(case: str, spec: tuple, quick: bool) -> list:
    thickness, step, refine, (fine_refine, fine_step) = spec
    converged, converged_s = run_once(case, thickness, fine_refine, fine_step, tolerance=0.25 * fine_step)
    results, headline = [], None
    fig = MplFigure(figsize=(11, 8))
    FigureCanvasAgg(fig)
    axes = fig.subplots(2, 2).ravel()
    table = Table(f"{case}: each knob changed alone from the defaults",
                  ["knob", "setting", "wall s", "error vs converged", "error vs tolerance 0", "default", "verdict"],
                  note=f"Converged answer: {fine_refine}x refinement, step {fine_step:g} nm "
                       f"({converged_s:.1f} s). Thickness {thickness:g} nm, k_exp {K_EXP}.")
    sequential = None
    for ax, (knob, settings) in zip(axes, knobs(step, refine, quick).items()):
        points = []
        for label, change, is_default in settings:
            kw = {"refine": refine, "step": step, "tolerance": None, "distance": "thesis", **change}
            run, wall = run_once(case, thickness, **kw)
            error = rms_error(run, converged, thickness)
            if knob == "batch tolerance" and kw["tolerance"] == 0.0:
                sequential = run
            points.append((pareto.Point(label, wall, error, is_default), run))
        verdict = pareto.verdict([p for p, _ in points])
        for p, run in points:
            vs_sequential = rms_error(run, sequential, thickness) if knob == "batch tolerance" else ""
            table.rows.append([knob, p.label, round(p.time, 3), round(p.error, 4), vs_sequential,
                               "yes" if p.default else "", verdict if p.default else ""])
            if p.default and knob == "batch tolerance":
                headline = Headline(f"planarize {case} (default settings, {thickness:g} nm)", f"{p.time:.2f} s",
                                    f"{100 * p.error:.1f} % RMS vs converged; "
                                    f"{100 * rms_error(run, sequential, thickness):.1f} % vs the sequential algorithm")
        pareto.plot(ax, [p for p, _ in points], title=f"{case}: {knob}", xlabel="wall time (s)",
                    ylabel="largest relative RMS error")
    fig.tight_layout()
    results += [table, Figure(f"planarize_accuracy_{case}", fig,
                              f"{case}: error against converged RMS vs wall time, one knob at a time; red star = default.")]
    if headline is not None:
        results.insert(0, headline)
    return results


def run(quick: bool) -> list:
    results = []
    for case, spec in (QUICK_CASES if quick else CASES).items():
        results += study(case, spec, quick)
    results.append(Note(
        "Reading the tables: on the thesis's 17 x 17 hill the grid dominates the error (coarse grids "
        "planarize too fast; 4x is ~20 % below the converged RMS at 1 nm); the step and the batch "
        "tolerance add a few percent. The batch tolerance's own error (vs tolerance 0, the sequential "
        "algorithm) at the default (a tenth of a step) is below 2 %; for comparison, breaking the "
        "sequential algorithm's exact ties with 1e-9 nm of height noise moves it by 3.5 % on the hill."))
    return results


if __name__ == "__main__":
    cli(run, __doc__)
