"""The pictures of ``qdots infer``: the corner plot of the posterior, the best-fitting film beside the micrograph
with both measure tables, and the posterior-predictive check; and for ``qdots compare``, the micrograph beside its
simulated film. Each ``*_figure`` returns a matplotlib Figure (drawn off screen); `qdots.cli.files` writes them.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from labrig.figures import save_figure

from ..micrograph.film import film_state
from ..micrograph.overlay import overlay_range, save_overlay_axes
from ..presets import MEAN_DIAMETER
from ..render import add_key, draw_state, robust_size_range, size_colours
from .compare import Comparison
from .forward import MEASURES, PARAMETERS, SUMMARIES
from .infer import Inference


def corner_figure(inference: Inference, bins: int = 30):
    """The posterior's marginals (histograms, the 90 % interval dashed, the thesis's value dotted) and its pairs
    (2-D histograms), each axis over its prior's range."""
    samples = inference.samples
    k = len(PARAMETERS)
    fig = Figure(figsize=(2.3 * k, 2.3 * k))
    FigureCanvasAgg(fig)
    axes = fig.subplots(k, k)
    for i, pi in enumerate(PARAMETERS):
        for j, pj in enumerate(PARAMETERS):
            ax = axes[i, j]
            if j > i:
                ax.set_axis_off()
                continue
            if i == j:
                ax.hist(samples[:, i], bins=bins, range=(pi.low, pi.high), color="tab:blue", alpha=0.8)
                row = inference.intervals[i]
                for v in (row["low"], row["high"]):
                    ax.axvline(v, color="black", ls="--", lw=1)
                ax.axvline(pi.thesis, color="tab:red", ls=":", lw=1.2)
                ax.set_yticks([])
                ax.set_title(f"{row['median']:.2f} [{row['low']:.2f}, {row['high']:.2f}]", fontsize="small")
            else:
                ax.hist2d(samples[:, j], samples[:, i], bins=bins, range=[[pj.low, pj.high], [pi.low, pi.high]],
                          cmap="Blues")
                ax.set_ylim(pi.low, pi.high)
            ax.set_xlim(pj.low, pj.high)
            if i == k - 1:
                ax.set_xlabel(pj.label, fontsize="small")
                if j < k - 1:  # the last tick would touch the next panel's first
                    ax.xaxis.set_major_locator(MaxNLocator(4, prune="upper"))
            else:
                ax.set_xticklabels([])
            if j == 0 and i > 0:
                ax.set_ylabel(pi.label, fontsize="small")
            elif j > 0:
                ax.set_yticklabels([])
    ax = axes[0, k - 1]  # the mass models' probabilities, in the empty corner
    ax.set_axis_on()
    names = [m["key"] for m in inference.mass_models]
    ax.barh(names, [m["probability"] for m in inference.mass_models], color="tab:blue", alpha=0.8)
    ax.axvline(1.0 / len(names), color="tab:red", ls=":", lw=1.2)
    ax.set_xlim(0.0, 1.0)
    ax.invert_yaxis()
    ax.tick_params(labelsize="small")
    ax.set_title("mass model: probability", fontsize="small")
    c = inference.conditions
    factors = np.array([row["calibration_spread"] for row in inference.intervals], dtype=float)  # as applied
    spread = (f"spread x{factors.min():.2f}-{factors.max():.2f} by the calibration, clipped to the prior's box"
              if np.isfinite(factors).all() else "no calibration fitted: intervals are the prior's")
    fig.suptitle(f"{inference.film.image.source}: posterior of the deposition parameters (sigma {c['sigma']:.3f}, "
                 f"coverage {c['coverage']:.3f};\n{len(samples):,} draws, {inference.films:,} training films; "
                 f"{spread}).\nDashed: 90 % interval; dotted red: the thesis's value (mass models: their prior)", fontsize="medium")
    fig.subplots_adjust(left=0.08, right=0.98, bottom=0.08, top=0.88, wspace=0.08, hspace=0.12)
    return fig


def measure_table_rows(inference: Inference) -> list[list[str]]:
    """Rows (measure, image, best film, predicted 90 % band) for the tables of the figures and files."""
    best = inference.best
    rows = []
    for row in inference.check:
        value = best.get(row["measure"])
        rows.append([row["label"] + (" *" if row["used"] else ""), f"{row['image']:.3g}",
                     "nan" if value is None else f"{float(value):.3g}", f"[{row['low']:.3g}, {row['high']:.3g}]"])
    return rows


def best_film_figure(inference: Inference):
    """The micrograph with its detections beside the best-fitting simulated film at the same nm scale, and the
    measures of both (with the predictive band) in a table below."""
    film = inference.film
    h, w = film.image.shape
    nm = film.nm_per_px if film.nm_per_px is not None else 1.0
    unit = "nm" if film.nm_per_px is not None else "image px"
    scale = film.summary["mean_diameter_px"] * nm / MEAN_DIAMETER  # nm (or image px) per board px
    state = inference.best["state"]
    board = replace(state, positions=state.positions * scale, radii=state.radii * scale,
                    box=(state.box[0] * scale, state.box[1] * scale), walls=state.walls * scale)
    fig = Figure(figsize=(14, 11.5))
    FigureCanvasAgg(fig)
    left = fig.add_axes((0.05, 0.36, 0.42, 0.58))
    right = fig.add_axes((0.55, 0.36, 0.42, 0.58))
    save_overlay_axes(film, left, extent_nm=(w * nm, h * nm))
    left.set_title(f"{film.image.source}: {film.summary['dots']} dots measured", fontsize="medium")
    draw_state(board, ax=right, show_time=False)
    right.set_xlim(0, board.box[0])
    right.set_ylim(0, board.box[1])
    b = inference.best
    right.set_title("best-fitting film: " + ", ".join(f"{p.key} {b[p.key]:.2f}" for p in PARAMETERS)
                    + f", seed {b['seed']}", fontsize="medium")
    for ax in (left, right):
        ax.set_aspect("equal")
        ax.set_xlabel(unit)
        ax.set_ylabel(unit)
    add_key(right, board, unit)
    table_ax = fig.add_axes((0.1, 0.02, 0.8, 0.27))
    table_ax.set_axis_off()
    table = table_ax.table(cellText=measure_table_rows(inference),
                           colLabels=["measure (* conditioned on)", "micrograph", "best film",
                                      "films from the posterior, 90 %"], loc="center", cellLoc="left")
    table.auto_set_font_size(False)
    table.set_fontsize(9)
    table.scale(1.0, 1.25)
    return fig


def check_figure(inference: Inference):
    """The posterior-predictive check: per measure, the predicted films' values (dots and their 90 % band) and the
    micrograph's (red)."""
    keys = list(MEASURES)
    cols = 4
    rows = math.ceil(len(keys) / cols)
    fig = Figure(figsize=(3.3 * cols, 2.4 * rows))
    FigureCanvasAgg(fig)
    axes = fig.subplots(rows, cols).ravel()
    rng = np.random.default_rng(0)
    for ax, key, row in zip(axes, keys, inference.check):
        values = np.array([r.get(key) for r in inference.predictive if r.get("status") == "ok"
                           and r.get(key) is not None], dtype=float)
        ax.plot(values, rng.uniform(-0.3, 0.3, len(values)), "o", color="tab:blue", ms=4, alpha=0.7)
        ax.axvspan(row["low"], row["high"], color="tab:blue", alpha=0.12)
        ax.axvline(row["image"], color="tab:red", lw=2)
        ax.set_yticks([])
        ax.set_ylim(-1, 1)
        ax.set_title(MEASURES[key] + (" *" if key in SUMMARIES else ""), fontsize="small",
                     color="black" if row["inside"] else "tab:red")
    for ax in axes[len(keys):]:
        ax.set_axis_off()
    inside = sum(row["inside"] for row in inference.check)
    fig.suptitle(f"Posterior-predictive check: {len(inference.predictive)} films drawn from the posterior (blue, "
                 f"band 90 %) against the micrograph (red); {inside} of {len(keys)} measures inside "
                 "(* conditioned on; titles in red: outside)", fontsize="medium")
    fig.subplots_adjust(left=0.03, right=0.98, bottom=0.08, top=0.86, wspace=0.12, hspace=0.7)
    return fig


def save_side_by_side(comparison: Comparison, path, dpi: int = 120) -> Path:
    """`side_by_side_figure`, written atomically to ``path``."""

    return save_figure(side_by_side_figure(comparison), path, dpi=dpi)


def side_by_side_figure(comparison: Comparison):
    """The image with its detections beside the first simulated film, both at the same nm scale (a
    matplotlib Figure)."""

    film = comparison.film
    h, w = film.image.shape
    nm = film.nm_per_px if film.nm_per_px is not None else 1.0
    unit = "nm" if film.nm_per_px is not None else "image px"
    scale = comparison.nm_per_board_px if math.isfinite(comparison.nm_per_board_px) else film.summary[
        "mean_diameter_px"] / MEAN_DIAMETER
    state = comparison.states[0]
    board = replace(state, positions=state.positions * scale, radii=state.radii * scale,
                    box=(state.box[0] * scale, state.box[1] * scale), walls=state.walls * scale)
    extent = max(w * nm, h * nm, *board.box)
    low, high = overlay_range(film)
    sim_low, sim_high = robust_size_range(board.radii)
    shared = (min(low * nm, sim_low), max(high * nm, sim_high))  # one colour scale, nm, for both panels
    fig = Figure(figsize=(14, 8.6))
    FigureCanvasAgg(fig)
    left, right = fig.subplots(1, 2)
    save_overlay_axes(film, left, extent_nm=(w * nm, h * nm), diameters=(shared[0] / nm, shared[1] / nm))
    left.set_xlim(0, extent)
    left.set_ylim(extent, 0)
    left.set_title(f"{film.image.source}: {film.summary['dots']} dots measured", fontsize="medium")
    draw_state(board, ax=right, show_time=False, colours=size_colours(board.radii, shared))
    right.set_xlim(0, extent)
    right.set_ylim(0, extent)
    exp = comparison.experiment
    right.set_title(f"simulated: {exp.deposition.n_dots} dots, sigma {exp.deposition.sigma:.3f}, masses ~ d^3, "
                    f"{exp.engine.kind} engine, seed {exp.seed}", fontsize="medium")
    for ax in (left, right):
        ax.set_aspect("equal")
        ax.set_xlabel(unit)
        ax.set_ylabel(unit)
    add_key(right, board, unit, diameters=shared)
    detected = film.detection
    sized = film_state(detected.centres[~detected.cut] * nm, detected.diameters[~detected.cut] * nm, (h * nm, w * nm))
    add_key(left, sized, unit, diameters=shared)
    fig.subplots_adjust(left=0.06, right=0.98, top=0.94, bottom=0.2, wspace=0.15)
    return fig
