"""One board, every number: packing, structure and LQE in one table and one figure (``qdots analyze``)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.cm import ScalarMappable
from matplotlib.colors import Normalize
from matplotlib.figure import Figure

from labrig.figures import check_dpi, save_figure
from labrig.validate import count

from .forster import TRAP_FRACTION, resolve_forster_radius
from .lqe import MAX_DRAWS, TrapAverage, film_lqe
from .packing import fill_within_radius, packing_summary
from .structure import Hexatic, RadialDistribution, clusters, hexatic_order, radial_distribution, voronoi_coordination


@dataclass(frozen=True)
class BoardReport:
    """Everything `board_report` measured; ``summary`` is the flat table (JSON-ready)."""

    summary: dict
    hexatic: Hexatic
    rdf: RadialDistribution | None
    lqe: TrapAverage | None


def board_report(state, rule: str = "text", forster_radius: float | None = None,
                 trap_fraction: float = TRAP_FRACTION, draws: int = 8, seed=0, lqe: bool = True,
                 forster_radii: float | None = None) -> BoardReport:
    """Packing figures, hexatic order, clusters, Voronoi coordination, g(r) and the film LQE of a board.

    Parameters
    ----------
    state : State
    rule : {"text", "code"}
        Neighbour rule (`qdots.analysis.neighbour_edges`).
    forster_radius : float, optional
        px; default the mean diameter (the thesis).
    forster_radii : float, optional
        R_F in mean dot radii instead (`qdots.analysis.forster.resolve_forster_radius`).
    trap_fraction : float
        Fraction of trap dots (thesis 1/3).
    draws : int
        Trap draws the LQE is averaged over (`qdots.analysis.lqe.film_lqe`), in [1, `qdots.analysis.lqe.MAX_DRAWS`].
    seed : int
        Seed of the trap draws.
    lqe : bool
        Compute the LQE (the costliest part on large boards).
    """
    if lqe:
        count("draws", draws, 1, MAX_DRAWS)  # before the costly parts
    summary = packing_summary(state, rule=rule)
    hexatic = hexatic_order(state, rule=rule)
    _, sizes = clusters(state, rule=rule)
    coordination = voronoi_coordination(state)
    bounded = coordination >= 0
    n = summary["n_dots"]
    summary.update(
        psi6_global=hexatic.global_order,
        psi6_local=hexatic.local_order,
        clusters=int(len(sizes)),
        largest_cluster_fraction=float(sizes[0] / n) if n else math.nan,
        voronoi_coordination=float(coordination[bounded].mean()) if bounded.any() else math.nan,
        size_spread=float(np.std(state.radii) / np.mean(state.radii)) if n else math.nan,
    )
    rdf = None
    box = getattr(state, "box", None)
    if n >= 2 and box is not None:
        rdf = radial_distribution(state, bins=80)
    average = None
    if lqe and n:
        radius_px = resolve_forster_radius(state.radii, forster_radius, forster_radii)
        average = film_lqe(state, draws=draws, seed=seed, forster_radius=forster_radius, forster_radii=forster_radii,
                           trap_fraction=trap_fraction)
        summary.update(
            lqe=average.mean, lqe_standard_error=average.standard_error, lqe_error_bound=average.error_bound,
            solution_lqe=average.solution_lqe,
            forster_radius_px=radius_px,
            trap_fraction=float(trap_fraction), trap_draws=int(draws), lqe_cutoff_px=average.cutoff,
        )
    return BoardReport(summary, hexatic, rdf, average)


def _correlation_text(summary: dict) -> str:
    """The size-separation correlation, or why it has no value (nan: equal sizes, or fewer than two pairs)."""
    value = summary["size_separation_correlation"]
    if math.isfinite(value):
        return f"{value:.3f}"
    if summary.get("size_spread") == 0:
        return "undefined for equal sizes"
    return "undefined (fewer than two neighbouring pairs)"


def table_rows(summary: dict) -> list[tuple[str, str]]:
    """The summary as (label, text) rows for `qdots.cli.commands.print_table`."""
    s = summary
    rows = [
        ("dots", f"{s['n_dots']}"),
        ("size spread (SD / mean diameter)", f"{100 * s['size_spread']:.1f} %"),
        ("interior fraction (>= 5 neighbours)", f"{s['interior_fraction']:.3f}"),
        ("mean neighbours (interior / all)", f"{s['mean_neighbours_interior']:.2f} / {s['mean_neighbours']:.2f}"),
        ("RMS excess separation (interior)", f"{s['rms_excess_separation']:.3f} px"),
        ("mean spacing (interior)", f"{s['mean_spacing']:.3f} px"),
        ("size-separation correlation", _correlation_text(s)),
        ("psi6 global / local", f"{s['psi6_global']:.3f} / {s['psi6_local']:.3f}"),
        ("clusters of neighbouring dots", f"{s['clusters']}; the largest holds {100 * s['largest_cluster_fraction']:.1f} "
                                          "% of the dots"),
        ("Voronoi coordination", f"{s['voronoi_coordination']:.2f}"),
        ("max overlap", f"{100 * s['max_overlap']:.3f} % of radius"),
    ]
    if "lqe" in s:
        rows += [
            ("film LQE (exact)", (f"{s['lqe']:.4f} +- {s['lqe_standard_error']:.4f} over {s['trap_draws']} trap draws"
                                  if s["trap_draws"] > 1 else f"{s['lqe']:.4f} for one trap draw (no standard error)")
             + f" (cutoff error <= {s['lqe_error_bound']:.1e})"),
            ("solution LQE", f"{s['solution_lqe']:.4f} (R_F {s['forster_radius_px']:g} px, "
                             f"traps {s['trap_fraction']:.3g}, cutoff {s['lqe_cutoff_px']:.1f} px)"),
        ]
    return rows


def save_report_png(state, report: BoardReport, path, dpi: int = 100) -> Path:
    """Four panels: ``|psi6|`` per dot, g(r), fill within radius, exciton yield per dot; 12 x 10.5 in at ``dpi``
    (at most `labrig.figures.MAX_DPI`), written atomically."""
    from ..render import draw_state

    check_dpi(dpi)  # before the drawing
    fig = Figure(figsize=(12, 10.5))
    FigureCanvasAgg(fig)
    ax = fig.subplots(2, 2)
    cmap = colormaps["viridis"]
    scale = ScalarMappable(Normalize(0.0, 1.0), cmap)
    draw_state(state, ax=ax[0, 0], colours=cmap(np.abs(report.hexatic.psi)), show_time=False)
    ax[0, 0].set_title(f"|psi6| per dot (global {report.summary['psi6_global']:.2f})")
    fig.colorbar(scale, ax=ax[0, 0], shrink=0.8, label="|psi6| (1: a perfect hexagon of neighbours)")
    if report.rdf is not None:
        ax[0, 1].plot(report.rdf.r, report.rdf.g)
        ax[0, 1].axhline(1.0, color="0.6", linewidth=0.8)
    ax[0, 1].set(xlabel="r (px)", ylabel="g(r)", title="radial distribution (edge-corrected)")
    box = getattr(state, "box", (1.0, 1.0))
    curve = fill_within_radius(state, np.linspace(0.05, 0.5, 30) * min(box))
    ax[1, 0].plot(curve.radius, curve.fill, marker=".")
    ax[1, 0].set(xlabel="radius around the board centre (px)", ylabel="covered fraction", ylim=(0, 1),
                 title="fill within radius")
    if report.lqe is not None:
        yields = report.lqe.first.yields
        assert yields is not None  # the exact result of a draw has them (TrapAverage.first)
        colours = cmap(yields)
        colours[report.lqe.first_traps] = (0, 0, 0, 1)
        draw_state(state, ax=ax[1, 1], colours=colours, show_time=False)
        ax[1, 1].set_title(f"emission probability per dot (traps black), LQE {report.lqe.mean:.3f}")
        fig.colorbar(scale, ax=ax[1, 1], shrink=0.8, label="probability that an exciton born here is emitted")
    else:
        ax[1, 1].set_axis_off()
    fig.tight_layout()
    return save_figure(fig, path, dpi, format="png")
