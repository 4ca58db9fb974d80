"""The kinetic-energy budget of a frame in both qdots engines: what the kicks and the pull inject, what the collisions remove, by mass class.

Why does the Chipmunk engine end its films 5-25 % hotter than the event engine (the thesis's algorithm)? Each
engine runs the same films, full size, seeds 154-158 (`--quick`: boards scaled down 10x, seeds 154-155), with
an `qdots.diagnostics.energy_budget.EnergyBudget` attached: the free film with masses ~ d^3 at sigma 10 % (the
``fig2-6`` setting, dots split into mass terciles) and with equal masses at sigma 0 (``fig2-2`` a).

* **Budget per frame**, over the settling (the last 100 s, every dot on the board): energy injected by the van
  der Waals pull and by the thermal kicks at the frame's start, energy removed by the collisions, their ratio,
  the kinetic energy held, and the mean speed of each class (time-averaged, and at the end).
* **Mean-speed history** in 50 s windows.
* **One frame from identical boards**: from each event film's final board, both engines run the same frames
  with the same kicks (10 seeds per board), so the first frame's velocity changes are identical and any
  difference is the engine's: energy removed in frame 1, pull injected in frame 2.
  The identical-board test also runs Chipmunk at a 3x and a 10x smaller ``overlap_tolerance`` (how far the plan
  lets a dot travel into a contact in one sub-step, the default 0.005 radii).
* Chipmunk both ways: impacts resolved at contact (``impacts = "contact"``, the default: every impact
  moved to where the impact at the instant of contact leaves the pair, `qdots.engine.contacts`) and where
  Chipmunk finds them, overlapped (``impacts = "overlap"``, the earlier default).

Run: ``python -m benchmarks.qdots_energy_budget [--quick] [--figures DIR]`` (about 15 minutes on this machine,
one process).
"""

from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np
from matplotlib.figure import Figure as MplFigure

import qdots
from qdots.analysis import packing_summary
from qdots.analysis.structure import clusters
from qdots.diagnostics.energy_budget import EnergyBudget
from qdots.experiment import build_simulation, populate
from qdots.presets import get_preset

from . import pinned
from .report import Figure, Headline, Note, Table, cli

#: The code this benchmark measures (besides itself): a commit to it after a run marks the run's section as
#: older than its code (`benchmarks.staleness`).
MEASURED_CODE = ("qdots/engine", "qdots/forces", "qdots/simulation.py", "qdots/experiment.py",
                 "qdots/diagnostics/energy_budget.py", "benchmarks/pinned.py")

#: The films: (label, sigma, mass model).
FILMS = (("masses ~ d^3, sigma 10 %", 0.10, "volume"), ("equal masses, sigma 0", 0.0, "equal"))
#: The engines compared: (label, engine kind, engine settings changed from the defaults).
ENGINES = (("event", "event", {}), ("Chipmunk, impacts overlapped (earlier default)", "chipmunk", {"impacts": "overlap"}),
           ("Chipmunk, impacts at contact (default)", "chipmunk", {}))
#: Further Chipmunk settings run in the identical-board test only, as in `ENGINES`.
TOLERANCES = (("Chipmunk overlapped, overlap_tolerance 0.0015", "chipmunk",
               {"impacts": "overlap", "overlap_tolerance": 0.0015}),
              ("Chipmunk overlapped, overlap_tolerance 0.0005", "chipmunk",
               {"impacts": "overlap", "overlap_tolerance": 0.0005}))
#: Mass classes of a film whose masses differ: terciles of d^3 for diameters ~ N(15, sigma 15) px.
TERCILE = 0.4307
CLASSES = ("light third", "middle third", "heavy third")
#: Window of the mean-speed history, s (scaled with the board in quick mode).
WINDOW = 50.0
#: Frames and repetitions of the identical-board test.
PAIRED_FRAMES, PAIRED_REPEATS = 3, 10


def mass_edges(sigma: float, model: str) -> tuple:
    """Class edges in mean-dot masses: terciles of (d / mean)^3 for a d^3 film, one class otherwise."""
    if model != "volume" or sigma == 0:
        return ()
    return ((1 - TERCILE * sigma) ** 3, (1 + TERCILE * sigma) ** 3)


def build(sigma: float, model: str, seed: int, engine: tuple, quick: bool):
    """The film's experiment and a simulation on ``engine`` with a budget attached (nothing run yet)."""
    base = next(exp for exp in get_preset("fig2-2", quick=0.1 if quick else False) if exp.deposition.sigma == 0.0)
    _, kind, changes = engine
    exp = base.replace(seed=seed, deposition=dataclasses.replace(base.deposition, sigma=sigma, mass_model=model),
                       engine=pinned.engine(kind, **changes))
    sim = build_simulation(exp)
    budget = EnergyBudget(mass_edges(sigma, model)).attach(sim)
    return exp, sim, budget


def film(sigma: float, model: str, seed: int, engine: tuple, quick: bool) -> dict:
    """One film with its budget: per-class means over the settling, the mean-speed history, the final board."""
    exp, sim, budget = build(sigma, model, seed, engine, quick)
    populate(sim, exp)
    budget.finish(sim)
    frames = budget.frames()
    state = sim.state()
    settled = frames.time >= exp.deposition.n_dots * exp.deposition.interval - 1e-9
    dots = frames.dots[settled].astype(float)

    def per_dot(a):
        return (a[settled] / np.maximum(dots, 1)).mean(axis=0)

    speed = frames.speed.sum(axis=1) / np.maximum(frames.dots.sum(axis=1), 1)
    window = WINDOW * (0.1 if quick else 1.0)
    edges = np.arange(0.0, frames.time[-1] + 0.02 + 1e-9, window)
    history = [float(speed[(frames.time >= a) & (frames.time < b)].mean()) for a, b in itertools.pairwise(edges)]
    classes = budget.classes_of(state.masses)
    final = np.hypot(*state.velocities.T)
    out = {"pull": per_dot(frames.injected_by(0)), "kicks": per_dot(frames.injected_by(1)),
           "removed": per_dot(frames.removed), "energy": per_dot(frames.start),
           "speed": per_dot(frames.speed), "final": np.array([final[classes == c].mean() if np.any(classes == c)
                                                               else np.nan for c in range(budget.n_classes)]),
           "ratio": frames.removed[settled].sum(axis=0) / frames.injected[settled].sum(axis=0),
           "all": {"pull": float(frames.injected_by(0)[settled].sum(1).mean() / dots.sum(1).mean()),
                   "kicks": float(frames.injected_by(1)[settled].sum(1).mean() / dots.sum(1).mean()),
                   "removed": float(frames.removed[settled].sum(1).mean() / dots.sum(1).mean()),
                   "energy": float(frames.start[settled].sum(1).mean() / dots.sum(1).mean()),
                   "ratio": float(frames.removed[settled].sum() / frames.injected[settled].sum()),
                   "speed": float(speed[settled].mean()), "final": float(final.mean()),
                   "aggregates": float(np.sum(clusters(state)[1] >= 5)),
                   "interior": float(packing_summary(state)["interior_fraction"])},
           "history": history, "windows": edges, "forces": frames.forces, "board": state,
           "impacts": float(frames.impacts[settled].mean())}
    return out


def paired(board, sigma: float, model: str, engine: tuple, seed: int) -> np.ndarray:
    """From ``board``, `PAIRED_FRAMES` frames on ``engine`` with the film's forces and ``seed``: per frame, the pull
    injected, the kicks injected and the energy removed (per dot), shape (3, frames)."""
    _, kind, changes = engine
    scene = qdots.Scene(box=board.box, positions=board.positions, radii=board.radii, masses=board.masses,
                        velocities=board.velocities, from_engine=True)
    sim = qdots.Simulation(scene, [qdots.VanDerWaals(), qdots.ThermalKicks()], seed=seed,
                           engine=pinned.engine(kind, **changes))
    budget = EnergyBudget(mass_edges(sigma, model)).attach(sim)
    sim.run(PAIRED_FRAMES * sim.dt)
    budget.finish(sim)
    f = budget.frames()
    return np.stack([f.injected_by(0).sum(1), f.injected_by(1).sum(1), f.removed.sum(1)]) / board.n_dots


def mean_se(values) -> tuple[float, float]:
    values = np.asarray(values, float)
    return float(np.mean(values)), float(np.std(values, ddof=1) / math.sqrt(values.size)) if values.size > 1 else math.nan


def pm(values, digits: int = 2) -> str:
    m, se = mean_se(values)
    return f"{m:.{digits}f} +- {se:.{digits}f}"


def run(quick: bool) -> list:
    seeds = (154, 155) if quick else tuple(range(154, 159))
    runs = {(f[0], e[0], seed): film(f[1], f[2], seed, e, quick) for f in FILMS for e in ENGINES for seed in seeds}
    scale = " (quick: boards scaled down 10x)" if quick else ""
    budget_table = Table(f"Energy budget per frame and per dot over the settling{scale}, mean +- standard error over "
                         f"seeds {seeds[0]}-{seeds[-1]} (energies in mean-dot mass px^2/s^2; removed / injected "
                         "over the settling)",
                         ["film", "dots", "engine", "injected by the pull", "injected by the kicks", "removed",
                          "removed / injected", "kinetic energy held", "mean speed, settling (px/s)",
                          "mean speed at the end (px/s)", "aggregates (>= 5 dots) at the end",
                          "interior fraction at the end"])
    for label, sigma, model in FILMS:
        names = CLASSES if mass_edges(sigma, model) else ("all",)
        for c, name in list(enumerate(names)) + ([(None, "all")] if len(names) > 1 else []):
            for engine, _, _ in ENGINES:
                rs = [runs[(label, engine, s)] for s in seeds]
                whole = c is None or len(names) == 1

                def get(key, rs=rs, c=c, whole=whole):
                    return [r["all"][key] if whole else r[key][c] for r in rs]

                budget_table.rows.append([label, name, engine, pm(get("pull")), pm(get("kicks")), pm(get("removed")),
                                          pm(get("ratio"), 3), pm(get("energy"), 0), pm(get("speed"), 1),
                                          pm(get("final"), 1), pm(get("aggregates"), 1) if whole else "",
                                          pm(get("interior"), 3) if whole else ""])
    windows = runs[(FILMS[0][0], ENGINES[0][0], seeds[0])]["windows"]
    history_table = Table(f"Mean dot speed (px/s) in {windows[1] - windows[0]:g} s windows{scale}, mean +- standard "
                          "error over seeds",
                          ["film", "engine", *(f"{a:g}-{b:g} s" for a, b in itertools.pairwise(windows))])
    for label, _, _ in FILMS:
        for engine, _, _ in ENGINES:
            hs = np.array([runs[(label, engine, s)]["history"] for s in seeds])
            history_table.rows.append([label, engine, *(pm(hs[:, k], 1) for k in range(hs.shape[1]))])
    # one frame from identical boards: the event films' final boards, each engine, the same kicks
    same, refs = {}, {}
    repeats = 3 if quick else PAIRED_REPEATS
    for label, sigma, model in FILMS:
        for seed in seeds:
            board = runs[(label, ENGINES[0][0], seed)]["board"]
            for rep in range(repeats):
                ref = paired(board, sigma, model, ENGINES[0], 100 * rep + seed)
                refs.setdefault(label, []).append(ref)
                for engine in ENGINES[1:] + TOLERANCES:
                    same.setdefault((label, engine[0]), []).append(paired(board, sigma, model, engine, 100 * rep + seed) - ref)
    paired_table = Table(f"From identical boards (each event film's final board, {repeats} kick seeds each): Chipmunk "
                         "minus event, per dot, frame by frame (frame 1 starts from the same velocities and gets the "
                         "same velocity changes; energies in mean-dot mass px^2/s^2)",
                         ["film", "engine", "removed in frame 1", "pull injected in frame 2", "pull injected in frame 3",
                          "event: removed in frame 1", "event: pull injected in frame 2"])
    for label, _sigma, _model in FILMS:
        ref = np.array(refs[label])
        for engine, *_ in ENGINES[1:] + TOLERANCES:
            d = np.array(same[(label, engine)])
            paired_table.rows.append([label, engine, pm(d[:, 2, 0]), pm(d[:, 0, 1]), pm(d[:, 0, 2]),
                                      pm(ref[:, 2, 0], 1), pm(ref[:, 0, 1], 1)])
    figure = budget_figure(runs, seeds)
    first = FILMS[0][0]
    speeds = {e: mean_se([runs[(first, e, s)]["all"]["speed"] for s in seeds]) for e, _, _ in ENGINES}
    pull = {e: mean_se(np.array(same[(first, e)])[:, 0, 1]) for e, _, _ in ENGINES[1:]}
    return [
        Headline("energy budget of the d^3 film at sigma 10 %, both engines",
                 f"{len(runs)} {'quick' if quick else 'full'} films, {len(seeds)} seeds",
                 "mean speed over the settling: " + ", ".join(f"{e} {m:.1f} +- {se:.1f}" for e, (m, se) in speeds.items())
                 + " px/s; pull injected in frame 2 from identical boards, Chipmunk - event: "
                 + ", ".join(f"{e} {m:+.2f} +- {se:.2f}" for e, (m, se) in pull.items())),
        budget_table, history_table, paired_table, figure,
        Note("The kicks inject the same in both engines (0.5 m |dv|^2 = 1.76 per dot per frame, whatever the mass, "
             "plus a cross term that averages to zero); the van der Waals pull injects about ten times more, and the "
             "collisions remove what both inject (removed / injected is 1 within the seed spread): the temperature is "
             "set by how much the pull injects for a given board. From identical boards and identical kicks, one "
             "frame of Chipmunk resolving impacts where it finds them (the earlier default) leaves the dots placed so that "
             "the next pull injects more: every impact is resolved only once the discs overlap, from the overlapped "
             "position, which leaves each pair that bounced (1 + e) times the overlap closer than the impact at "
             "contact does, and the proxy, which acts only from 0.1 px and is steepest there, then slows fewer "
             "separating pairs. Resolving each impact at contact (the default) removes the excess and the films' "
             "extra heat."),
    ]


def budget_figure(runs: dict, seeds) -> Figure:
    """Mean-speed histories (mean +- SE band), and injected and removed per frame by mass class, for each film."""
    fig = MplFigure(figsize=(13, 9.5))
    colours = dict(zip((engine for engine, _, _ in ENGINES), ("tab:blue", "tab:red", "tab:green")))
    for col, (label, sigma, model) in enumerate(FILMS):
        ax = fig.add_subplot(2, 2, col + 1)
        for engine, _, _ in ENGINES:
            hs = np.array([runs[(label, engine, s)]["history"] for s in seeds])
            w = runs[(label, engine, seeds[0])]["windows"]
            mid = 0.5 * (w[:-1] + w[1:])
            m, se = hs.mean(0), hs.std(0, ddof=1) / math.sqrt(len(seeds))
            ax.plot(mid, m, "-o", color=colours[engine], label=engine, ms=4)
            ax.fill_between(mid, m - se, m + se, color=colours[engine], alpha=0.2)
        ax.set_xlabel("time (s)")
        ax.set_ylabel("mean dot speed (px/s)")
        ax.set_title(f"{label}: mean speed, mean +- SE over {len(seeds)} seeds", fontsize=10)
        ax.legend(fontsize=8, loc="best")
        ax = fig.add_subplot(2, 2, col + 3)
        names = CLASSES if mass_edges(sigma, model) else ("all dots",)
        width = 0.8 / (2 * len(ENGINES))
        for k, (engine, _, _) in enumerate(ENGINES):
            rs = [runs[(label, engine, s)] for s in seeds]
            classes = len(names)

            def stat(key, rs=rs, classes=classes):
                values = np.array([r[key] if classes > 1 else [r["all"][key]] for r in rs])
                if key == "pull":  # injected: the pull and the kicks
                    values = values + np.array([r["kicks"] if classes > 1 else [r["all"]["kicks"]] for r in rs])
                return values.mean(0), values.std(0, ddof=1) / math.sqrt(len(seeds))

            x = np.arange(len(names)) + (2 * k + 0.5 - len(ENGINES)) * width
            style = {"color": colours[engine], "edgecolor": "black", "linewidth": 0.4, "capsize": 2, "ecolor": "black"}
            (injected, injected_se), (removed, removed_se) = stat("pull"), stat("removed")
            ax.bar(x, injected, width, yerr=injected_se, alpha=0.9, label=f"{engine}: injected", **style)
            ax.bar(x + width, removed, width, yerr=removed_se, alpha=0.4, hatch="//", label=f"{engine}: removed",
                   **style)
        ax.axhline(0.0, color="black", linewidth=0.6)
        ax.set_xticks(np.arange(len(names)))
        ax.set_xticklabels(names)
        ax.set_ylabel("energy per dot per frame (mean-dot mass px^2/s^2)")
        ax.set_title(f"{label}, settling: injected (pull + kicks, solid) and removed (hatched) per frame", fontsize=9)
        handles = ax.get_legend_handles_labels()
    fig.legend(*handles, loc="lower center", ncol=3, fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.07, 1, 1))
    return Figure("qdots_energy_budget", fig,
                  "The two engines' energy budgets: top, the mean dot speed in 50 s windows (mean +- standard error "
                  "over seeds); bottom, energy injected per dot per frame by the van der Waals pull and the kicks, "
                  "and removed by the collisions, by mass class, over the settling (a class's 'removed' includes what "
                  "the collisions pass to the other classes).")


def main(argv: list[str] | None = None) -> int:
    return cli(run, __doc__.splitlines()[0], argv)


if __name__ == "__main__":
    raise SystemExit(main())
