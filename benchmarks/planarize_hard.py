"""planarize's continuum engine on hard maps: a step, a crease, a cusp, noise and one-pixel features, its stated error against the true one.

Each map has 17 x 17 points at 0.25 nm (open edges) and grows 1 nm of oxide (k_exp 2.3):

* **step**: a 1 nm step between two columns of points;
* **ridge**: a piecewise-linear ridge 1 nm high, a crease along its top;
* **cusp**: a hollow whose height grows as the square root of the distance from its centre (an infinite slope
  there);
* **noise**: white noise of 0.3 nm;
* **pit, 1 nm** and **pit, 4 nm**: one point 1 nm or 4 nm below the rest;
* **checkerboard**: heights alternating by 0.5 nm from point to point.

The default run (``rtol`` 0.02, `benchmarks.planarize_continuum.CONTINUUM`) states its error
(`planarize.engines.resolution`); beside it, its true error against the converged answer: the 16x run corrected at
the slope of its last three refinements (`benchmarks.planarize_continuum.converged`). Where those refinements' changes
do not shrink (the slope's order under 0.5), the converged answer is itself uncertain, and the table says so.

Run: ``python -m benchmarks.planarize_hard [--quick]``.
"""

from __future__ import annotations

import math

import numpy as np
from matplotlib.figure import Figure as MplFigure

from planarize import Surface
from planarize.engines import Continuum
from planarize.metrics import ESTIMATED, pixel_curvature

from .planarize_continuum import CONTINUUM, case_results
from .report import Figure, Headline, Note, Table, cli

#: The code this benchmark measures (besides itself): a commit to it after a run marks the run's section as
#: older than its code (`benchmarks.staleness`).
MEASURED_CODE = ("planarize",)

POINTS, SPACING, THICKNESS = 17, 0.25, 1.0
FACTORS = (1, 2, 4, 8, 16)
#: Maps whose converged answer is left at 8x: the checkerboard's time steps grow 75-fold from 4x to 8x.
COARSE_TRUTH = ("checkerboard",)
QUICK_FACTORS, QUICK_SETTINGS = (0.5, 1, 2, 4), Continuum(rtol=0.02, refine=None, max_refine=2, stability=0.9,
                                                           threads=None)
#: A converged answer whose last refinements' changes shrink at an order under this is itself uncertain (the
#: slope is clipped to 0.5 there).
SHRINKING = 0.5


def hard_maps() -> dict[str, Surface]:
    """The benchmark's maps (see the module docstring), heights in nm about 4 nm."""
    n = POINTS
    x, y = np.meshgrid(np.arange(n) * SPACING, np.arange(n) * SPACING, indexing="ij")
    centre = (n - 1) * SPACING / 2
    step = np.full((n, n), 4.0)
    step[:, n // 2:] = 5.0
    pits = {}
    for depth in (1.0, 4.0):
        pits[depth] = np.full((n, n), 4.0)
        pits[depth][n // 2, n // 2] -= depth
    heights = {
        "step": step,
        "ridge": 5.0 - np.abs(x - centre) / centre,
        "cusp": 4.0 + np.sqrt(np.hypot(x - centre, y - centre) / centre),
        "noise": 4.0 + 0.3 * np.random.default_rng(0).standard_normal((n, n)),
        "pit, 1 nm": pits[1.0],
        "pit, 4 nm": pits[4.0],
        "checkerboard": 4.0 + 0.5 * (np.add.outer(np.arange(n), np.arange(n)) % 2),
    }
    return {name: Surface(z, SPACING) for name, z in heights.items()}


def stated_cell(stated: float, true: float, doubt: str) -> list:
    """The table's three cells of one quantity: stated, true and their ratio; ``doubt`` says why the truth is not
    scored ("" where it is)."""
    shown = "not asymptotic" if math.isnan(stated) else stated
    if doubt:
        return [shown, f"{true:.3g} ({doubt})", f"({doubt})"]
    return [shown, true, "not asymptotic" if math.isnan(stated) else stated / true]


def ratio_figure(points: dict) -> MplFigure:
    """Stated over true error of each map's four quantities (``points``: map -> four ratios, NaN where no number is
    stated, None where the truth is not known), on a log scale with the goal's band, 0.5-2, shaded."""
    figure = MplFigure(figsize=(7.0, 4.0))
    ax = figure.subplots()
    ax.axhspan(0.5, 2.0, color="0.9", label="within 2x (the goal)")
    labels = ("metal RMS", "metal z-range", "oxide RMS", "oxide z-range")
    for k, label in enumerate(labels):
        x = np.arange(len(points)) + 0.15 * (k - 1.5)
        ratios = [values[k] for values in points.values()]
        scored = [(xi, r) for xi, r in zip(x, ratios) if r is not None and not math.isnan(r)]
        if scored:
            ax.plot(*zip(*scored), "o", color=f"C{k}", label=label)
        withheld = [xi for xi, r in zip(x, ratios) if r is not None and math.isnan(r)]
        ax.plot(withheld, np.full(len(withheld), 0.25), "x", color="0.4",
                label="no number stated (drawn at 0.25)" if k == 0 else None)
    ax.set_yscale("log")
    ax.set_ylim(0.2, 5.0)
    ticks = (0.25, 0.5, 1.0, 2.0, 4.0)
    ax.set_yticks(ticks, [f"{t:g}" for t in ticks])
    ax.minorticks_off()
    ax.set_xticks(np.arange(len(points)), list(points), rotation=20)
    ax.set_ylabel("stated / true error")
    ax.set_title("Continuum engine on hard 17 x 17 maps (quantities with a known truth)")
    ax.legend(fontsize="small", ncol=2)
    figure.tight_layout()
    return figure


def run(quick: bool = False) -> list:
    maps = hard_maps()
    factors, settings = (QUICK_FACTORS, QUICK_SETTINGS) if quick else (FACTORS, CONTINUUM)
    if quick:
        maps = {k: maps[k] for k in ("step", "ridge")}
    table = Table("Stated against true error at the default (rtol 0.02), 17 x 17 points at 0.25 nm, 1 nm of oxide: "
                  "largest over the recorded thicknesses (%)",
                  ["map", "pixel curvature", "refinement chosen", "wall (s)", "orders to the truth",
                   *[f"{c.replace('_nm', '').replace('_', ' ')} {what}" for c in ESTIMATED
                     for what in ("stated", "true", "ratio")]])
    convergence = Table("Convergence: largest error over the recorded thicknesses (%), against the converged answer",
                        ["map", "refinement", "grid", "steps", "wall (s)", "metal RMS", "oxide RMS", "metal z-range",
                         "oxide z-range"])
    ratios: list[float] = []
    uncertain = withheld = 0
    points: dict[str, list] = {}
    for name, surface in maps.items():
        factors_run = factors[:-1] if name in COARSE_TRUTH else factors
        rows, default, orders = case_results(name, lambda s=surface: s, THICKNESS, factors_run, settings)
        convergence.rows += rows
        own = default[1] >= factors_run[-1]  # the run chose the finest grid: no independent truth
        cells = []
        for k, column in enumerate(ESTIMATED):
            stated, true, _ = default[3 + 3 * k: 6 + 3 * k]
            doubt = ("truth from the run's own grids" if own else
                     "uncertain: the changes do not shrink" if orders[column] <= SHRINKING else "")
            cells += stated_cell(stated, true, doubt)
            points.setdefault(name, []).append(None if doubt else stated / true)
            if doubt:
                uncertain += 1
            elif math.isnan(stated):
                withheld += 1
            else:
                ratios.append(stated / true)
        table.rows.append([name, pixel_curvature(surface), default[1], default[2],
                           ", ".join(f"{orders[c]:.2g}" for c in ESTIMATED), *cells])
    scored = np.asarray(ratios, dtype=float)
    within = int(((scored >= 0.5) & (scored <= 2.0)).sum())
    verdict = (f"stated {len(scored)} of {len(scored) + withheld} quantities with a converged truth, within 2x: "
               f"{within}" + (f" (ratios {scored.min():.2g}-{scored.max():.2g})" if len(scored) else "")
               + f"; {withheld} not asymptotic (no number); {uncertain} with an uncertain truth")
    return [
        Headline(f"planarize continuum on {len(maps)} hard 17 x 17 maps (default rtol 0.02)", "see table", verdict),
        table,
        Figure("planarize_hard_ratios", ratio_figure(points),
               "Stated over true error at the grid the default run chooses; x: no number stated (not asymptotic); a "
               "quantity whose truth is not known is left out"),
        Note("Stated: the run's own estimate (history columns `*_error_nm`); true: its difference from the converged "
             "answer, the finest run corrected at the slope of the last three refinements (orders in the fifth "
             "column: metal RMS, metal z-range, oxide RMS, oxide z-range). Where that slope's order is 0.5 or less the "
             "changes do not shrink by the finest grid run, so the converged answer is not known and the quantity is "
             "not scored. " + verdict + "."),
        convergence,
    ]


if __name__ == "__main__":
    raise SystemExit(cli(run, __doc__.splitlines()[0]))
