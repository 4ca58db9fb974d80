"""planarize's continuum engine: convergence, its stated error against the true one, and speed on AFM-size maps.

* **Convergence.** Each case is computed at refinements 1/2 ... 8 (or 16) of its grid; the converged
  answer is the finest run corrected by Richardson's rule with the order observed over the three
  finest. Errors are the largest relative differences over the recorded thicknesses (RMS against
  at least 1 % of its starting value).
* **Stated against true error.** The default run (``rtol`` 0.02) of each case states its error
  (`planarize.engines.resolution`); beside it, its true error against the converged answer.
* **The thesis's algorithm.** The fast engine on the hill at 4x ... 32x refinement, against the
  continuum engine's converged answer: the thesis's algorithm converges to it.
* **The physics.** The thesis's rule against the ``"conformal"`` rule (uniform recession of the
  metal, the oxide its conformal coat) at k_exp 1.3 (Al) and 2.3 (Ta).
* **Speed.** The 1025 x 1025 periodic random film of `planarize_fast` to 200 nm and a 512 x 512 AFM
  map imported from .gwy (`benchmarks.afm_map`: rendered, not measured) to 100 nm, at the defaults,
  with peak memory (each in a child process).

Run: ``python -m benchmarks.planarize_continuum [--quick]``.
"""

from __future__ import annotations

import math
import multiprocessing
import resource
import tempfile
import time
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure as MplFigure
from scipy.ndimage import gaussian_filter

from planarize import Model, Surface, anodize, surfaces
from planarize.anodize import record_run
from planarize.engines import Continuum
from planarize.engines.continuum import ContinuumEngine
from planarize.metrics import ESTIMATED

from .report import Figure, Headline, Note, Table, cli

#: The code this benchmark measures (besides itself): a commit to it after a run marks the run's section as
#: older than its code (`benchmarks.staleness`).
MEASURED_CODE = ("planarize",)

#: case -> (surface builder, thickness nm, refinements computed)
CASES = {
    "hill, open": (lambda: surfaces.hill(), 1.0, (0.5, 1, 2, 4, 8, 16)),
    "hill, periodic": (lambda: surfaces.hill(boundary="periodic"), 1.0, (0.5, 1, 2, 4, 8)),
    "depression, open": (lambda: surfaces.depression(), 1.0, (0.5, 1, 2, 4, 8)),
    "depression, periodic": (lambda: surfaces.depression(boundary="periodic"), 1.0, (0.5, 1, 2, 4, 8)),
    "random 8 nm, periodic": (lambda: surfaces.random_roughness(8.0, thickness=4.0, scales=((2.0, 0.5),),
                                                                boundary="periodic", seed=3), 1.0, (0.5, 1, 2, 4, 8, 16)),
    "Ta film, open": (lambda: surfaces.random_roughness(seed=1), 200.0, (0.5, 1, 2, 4)),
    "smooth 129^2, periodic": (lambda: smooth_film(129), 200.0, (0.5, 1, 2, 4)),
}
QUICK_CASES = {"hill, open": (CASES["hill, open"][0], 1.0, (0.5, 1, 2, 4))}
ROWS = 10
FLOOR = 0.01

#: The continuum engine as this benchmark runs it, every knob given (its defaults of 0.3.0).
CONTINUUM = Continuum(rtol=0.02, refine=None, max_refine=8, stability=0.9, threads=None)


def smooth_film(n: int, seed: int = 0) -> Surface:
    """The `planarize_fast` benchmark's film: periodic smoothed noise, 5 nm spacing, RMS 6 nm."""
    z = gaussian_filter(np.random.default_rng(seed).normal(size=(n, n)), sigma=4.0, mode="wrap")
    return Surface(1000.0 + 6.0 * z / z.std(), 5.0, "periodic")


def level(surface: Surface, thickness: float, factor: float, rule: str = "thesis") -> tuple[dict, float, int, str]:
    """The history of one resolution (every ``thickness / ROWS``), its wall time, its steps and its grid."""
    engine = ContinuumEngine(surface, None, Model(rule=rule), Continuum(), factor)
    start = time.perf_counter()
    table, _, _ = record_run(engine, thickness, np.linspace(0, thickness, ROWS + 1), np.zeros(0), max_sweeps=10**9)
    return table, time.perf_counter() - start, engine.iterations, " x ".join(map(str, engine.inner.shape))


def point_steps(level: tuple) -> int:
    """A `level`'s time steps times its grid points."""
    rows, cols = map(int, level[3].split(" x "))
    return level[2] * rows * cols


def converged(levels: dict) -> dict:
    """Each estimated column's converged values: the finest level plus Richardson's correction at the order of
    its last refinements (clipped to [0.5, 4]); and those orders. The order is the least-squares slope of the
    logarithms of the last three changes (four finest levels), or of the last two (three levels): one ratio of two
    changes scatters between 0.4 and 2.5 on a real AFM map's crop where the slope over three settles near 1.2."""
    factors = sorted(levels)
    out, orders = {}, {}
    for column in ESTIMATED:
        values = [np.asarray(levels[f][0][column]) for f in factors[-4:]]
        changes = np.array([np.linalg.norm(b - a) for a, b in zip(values, values[1:])])
        if changes[-1] > 0 and (changes > 0).all():
            slope = np.polyfit(np.arange(len(changes)), np.log2(changes), 1)[0]
            p = float(np.clip(-slope, 0.5, 4.0))
        else:
            p = 2.0
        b, c = values[-2:]
        out[column], orders[column] = c + (c - b) / (2 ** p - 1), p
    return out, orders


def relative(values, truth) -> np.ndarray:
    truth = np.asarray(truth, dtype=float)
    return np.abs(np.asarray(values) - truth) / np.maximum(np.abs(truth), FLOOR * abs(truth[0]))


def case_results(name: str, builder, thickness: float, factors, settings: Continuum = CONTINUUM,
                 finest_after: float = np.inf) -> tuple[list, list, dict]:
    """The convergence rows of one case, its default run's stated and true errors, and the observed orders; the
    default run is ``settings`` (the converged answer comes from the finest of ``factors``, `converged`; a level
    finer than the default run may choose is left out when the one before it took more than ``finest_after`` point
    steps: its time steps times its grid points, a measure of its cost that, unlike its wall time, is the same on
    every run). A stated error the run does not give
    (its quantity not asymptotic: `planarize.engines.resolution`) is NaN, its ratio too."""
    surface = builder()
    levels = {}
    for f in factors:
        if levels and f > settings.max_refine and point_steps(levels[max(levels)]) > finest_after:
            break
        levels[f] = level(surface, thickness, f)
    truth, orders = converged(levels)
    rows = []
    for f in sorted(levels)[:-1]:
        table, wall, steps, shape = levels[f]
        errors = {c: relative(table[c], truth[c]).max() for c in ESTIMATED}
        rows.append([name, f, shape, steps, wall, 100 * errors["metal_rms_nm"], 100 * errors["oxide_rms_nm"],
                     100 * errors["metal_zrange_nm"], 100 * errors["oxide_zrange_nm"]])
    start = time.perf_counter()
    run = anodize(surface, thickness, Model(), settings, record=ROWS)
    wall = time.perf_counter() - start
    stated, true = {}, {}
    for c in ESTIMATED:
        scale = np.maximum(np.abs(truth[c]), FLOOR * abs(truth[c][0]))
        error = run.history[c.replace("_nm", "_error_nm")] / scale
        stated[c] = math.nan if np.isnan(error).any() else float(np.max(error))
        true[c] = float(relative(run.history[c], truth[c]).max())
    default = [name, run.parameters["refine"], wall, *[x for c in ESTIMATED for x in
                                                       (100 * stated[c], 100 * true[c], stated[c] / true[c])]]
    return rows, default, orders


def thesis_agreement(quick: bool) -> Table:
    """The fast engine on the hill at growing refinement against the continuum engine's converged answer."""
    reference = anodize(surfaces.hill(), 1.0, record=ROWS, engine=Continuum(refine=8)).history
    table = Table("The thesis's algorithm converges to the continuum engine (hill, open, k_exp 2.3, to 1 nm)",
                  ["engine", "grid", "step (nm)", "wall (s)", "metal RMS at 1 nm", "oxide RMS at 1 nm",
                   "largest RMS difference (%)"])
    for refine, step in ((4, 0.01), (8, 0.01), (16, 0.005)) + (() if quick else ((32, 0.0025),)):
        start = time.perf_counter()
        h = anodize(surfaces.hill(refine=refine), 1.0, Model(step=step), "fast", record=ROWS).history
        wall = time.perf_counter() - start
        worst = max(relative(h[c][1:], reference[c][1:]).max() for c in ("metal_rms_nm", "oxide_rms_nm"))
        n = 4 * refine + 1
        table.rows.append(["thesis (fast)", f"{n} x {n}", step, wall, h["metal_rms_nm"][-1], h["oxide_rms_nm"][-1],
                           100 * worst])
    table.rows.append(["continuum, 8x (reference)", "17 x 17 refined 8x", "", "", reference["metal_rms_nm"][-1],
                       reference["oxide_rms_nm"][-1], ""])
    return table


def rules(quick: bool) -> Table:
    table = Table("Which ingredient planarizes: the thesis's rule against uniform recession under a conformal oxide",
                  ["surface", "k_exp", "rule", "metal RMS (nm)", "oxide RMS (nm)", "metal z-range (nm)",
                   "oxide z-range (nm)", "stated error (%)", "wall (s)"])
    cases = [("hill", surfaces.hill(), 1.0), ("depression", surfaces.depression(), 1.0)]
    if not quick:
        cases.append(("Ta film, periodic", surfaces.random_roughness(seed=1, boundary="periodic"), 200.0))
    for name, surface, thickness in cases:
        for k_exp in (1.3, 2.3):
            for rule in ("thesis", "conformal"):
                start = time.perf_counter()
                run = anodize(surface, thickness, Model(k_exp=k_exp, rule=rule), CONTINUUM, record=4)
                h = run.history
                table.rows.append([name, k_exp, rule, f"{h['metal_rms_nm'][0]:.3g} -> {h['metal_rms_nm'][-1]:.3g}",
                                   f"{h['oxide_rms_nm'][0]:.3g} -> {h['oxide_rms_nm'][-1]:.3g}",
                                   f"{h['metal_zrange_nm'][0]:.3g} -> {h['metal_zrange_nm'][-1]:.3g}",
                                   f"{h['oxide_zrange_nm'][0]:.3g} -> {h['oxide_zrange_nm'][-1]:.3g}",
                                   100 * run.parameters["estimated_error"], time.perf_counter() - start])
    return table


def _timed(job, queue) -> None:
    try:
        start = time.perf_counter()
        result = job()
        queue.put((time.perf_counter() - start, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20, result))
    except BaseException as exc:  # the parent must hear of it, or it would wait for ever
        queue.put(exc)


def in_child(job):
    """(wall s, peak resident GB, result) of ``job()`` in a fresh process (its own peak memory)."""
    context = multiprocessing.get_context("fork")
    queue = context.Queue()
    process = context.Process(target=_timed, args=(job, queue))
    process.start()
    out = queue.get()
    process.join()
    if isinstance(out, BaseException):
        raise RuntimeError(f"the timed job failed: {out!r}") from out
    return out


def summary(run) -> tuple:
    h, p = run.history, run.parameters
    return (p["refine"], p["estimated_error"], h["metal_rms_nm"][0], h["metal_rms_nm"][-1], h["oxide_rms_nm"][-1],
            [lvl["steps"] for lvl in p["levels"] if "steps" in lvl], {c: np.asarray(h[c]) for c in ESTIMATED})


def film_job(n: int):
    return lambda: summary(anodize(smooth_film(n), 200.0, Model(), CONTINUUM, record=50))


def afm_job(pixels: int, path: Path, refine: int | None = None):
    def job():
        from planarize.cli.commands import import_scene

        scene = import_scene(path, thickness=100.0, level=True)
        return summary(scene.anodize(engine=Continuum(refine=refine)) if refine else scene.anodize())
    return job


def change_at_twice(default: dict, finer: dict) -> float:
    """The largest relative change of RMS and z-range when the grid is refined 2x: a measured lower bound of
    the default run's true error (about 0.65 of it at order 1.5)."""
    return max(relative(default[c], finer[c]).max() for c in ESTIMATED)


def stated(error: float) -> str:
    """A run's stated error, %, or why it states none."""
    return f"{100 * error:.2g} %" if math.isfinite(error) else "none (the map's own grid: see the rules)"


def speed(quick: bool) -> tuple[Table, list]:
    from .afm_map import render, write_gwy

    table = Table("Real maps at the default tolerance (rtol 0.02), 2 cores",
                  ["map", "thickness (nm)", "wall (s)", "peak memory (GB)", "grid run", "stated error",
                   "true error (%)", "metal RMS (nm)", "steps (reported grid, companion)"])
    heads = []
    n_film, pixels = (257, 128) if quick else (1025, 512)
    wall, peak, (refine, error, rms0, rms1, oxide1, steps, _) = in_child(film_job(n_film))
    table.rows.append([f"periodic random film {n_film} x {n_film}, 5 nm", 200, wall, peak, f"{refine:g}x",
                       stated(error), "see the smooth 129 x 129 film", f"{rms0:.3g} -> {rms1:.3g}", steps])
    heads.append(Headline(f"planarize continuum: periodic {n_film}x{n_film} to 200 nm", f"{wall:.1f} s",
                          f"stated error {stated(error)}; peak memory {peak:.2f} GB"))
    with tempfile.TemporaryDirectory() as folder:
        path = write_gwy(Path(folder) / "ta_afm.gwy", render(pixels, 2000.0 * pixels / 512), 2000.0 / 512)
        wall, peak, (refine, error, rms0, rms1, oxide1, steps, history) = in_child(afm_job(pixels, path))
        finer = in_child(afm_job(pixels, path, refine=2 * int(refine)))[2][-1]
    change = change_at_twice(history, finer)
    table.rows.append([f"AFM map {pixels} x {pixels} (.gwy, rendered), 3.9 nm", 100, wall, peak, f"{refine:g}x",
                       stated(error), f">= {100 * change:.2g} (the change at {2 * refine:g}x)", f"{rms0:.3g} -> {rms1:.3g}",
                       steps])
    heads.append(Headline(f"planarize continuum: AFM map {pixels}x{pixels} (.gwy) to 100 nm", f"{wall:.1f} s",
                          f"stated error {stated(error)}, true error at least {100 * change:.2g} %; peak memory "
                          f"{peak:.2f} GB"))
    return table, heads


def convergence_figure(curves: dict) -> MplFigure:
    figure = MplFigure(figsize=(6.4, 4.4))
    ax = figure.subplots()
    for name, (spacing, error) in curves.items():
        ax.loglog(spacing, error, marker="o", label=name)
    x = np.array([min(min(s) for s, _ in curves.values()), max(max(s) for s, _ in curves.values())])
    for order, style in ((1, ":"), (2, "--")):
        ax.loglog(x, 1.0 * (x / x[-1]) ** order, "k" + style, linewidth=0.8, label=f"order {order}")
    ticks = [2.0 ** k for k in range(-4, 2)]
    ax.set_xticks(ticks, [f"{t:g}" for t in ticks])
    ax.minorticks_off()
    ax.set_xlabel("grid spacing / the surface's own")
    ax.set_ylabel("largest RMS error (%), metal and oxide")
    ax.set_title("Continuum engine: error against grid spacing")
    ax.legend(fontsize="small")
    figure.tight_layout()
    return figure


def run(quick: bool = False) -> list:
    cases = QUICK_CASES if quick else CASES
    conv = Table("Convergence: largest error over the recorded thicknesses (%), against the converged answer",
                 ["case", "refinement", "grid", "steps", "wall (s)", "metal RMS", "oxide RMS", "metal z-range",
                  "oxide z-range"])
    stated = Table("Stated against true error at the default (rtol 0.02): largest over the recorded thicknesses (%)",
                   ["case", "refinement chosen", "wall (s)",
                    *[f"{c.replace('_nm', '').replace('_', ' ')} {what}" for c in ESTIMATED
                      for what in ("stated", "true", "ratio")]])
    orders = Table("Orders of convergence observed over the three finest grids (RMS and z-range)",
                   ["case", *[c.replace("_nm", "").replace("_", " ") for c in ESTIMATED]])
    curves = {}
    for name, (builder, thickness, factors) in cases.items():
        rows, default, order = case_results(name, builder, thickness, factors)
        conv.rows += rows
        stated.rows.append(default)
        orders.rows.append([name, *[order[c] for c in ESTIMATED]])
        curves[name] = ([1 / r[1] for r in rows], [max(r[5], r[6]) for r in rows])
    results = [conv, orders, stated, Figure("planarize_continuum_convergence", convergence_figure(curves),
                                            "Largest RMS error of the continuum engine against grid spacing")]
    results += [thesis_agreement(quick), rules(quick)]
    table, heads = speed(quick)
    results.append(table)
    hill = stated.rows[0]
    results.insert(0, Headline("planarize continuum: thesis hill 17x17 to 1 nm (default rtol 0.02)",
                               f"{hill[2]:.2f} s", f"metal RMS error {hill[4]:.2g} % (stated {hill[3]:.2g} %), "
                               f"oxide {hill[7]:.2g} % (stated {hill[6]:.2g} %)"))
    results[1:1] = heads
    results.append(Note("The converged answer of each case is its finest run corrected by Richardson's rule; the "
                        "stated error is the run's own estimate (history columns `*_error_nm`), the true error its "
                        "difference from the converged answer. The smooth 129 x 129 film has the statistics of the "
                        "1025 x 1025 speed case: its true error stands for that run's."))
    return results


if __name__ == "__main__":
    raise SystemExit(cli(run, __doc__.splitlines()[0]))
