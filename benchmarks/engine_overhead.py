"""qdots cost per step against N (300 to 100,000 dots), our forces over bare pymunk, and the overlap.

For each N two scenes of 15 px dots are warmed up under van der Waals + thermal
kicks + drag: ``loose`` (square lattice, 17 px pitch, ~2 contacts per dot) and
``packed`` (hexagonal at contact, ~6 contacts per dot, like a settled film). From
that same warmed state two simulations are timed alternately in chunks (timings
on this machine drift 20-40 % between runs, so interleaving keeps the
comparison fair), both on the pinned Chipmunk settings (`benchmarks.pinned.CHIPMUNK`: the defaults of
0.3.0, the thesis's 20 ms frame, every van der Waals pair pulled every frame):

* ``full``: ``VanDerWaals() + ThermalKicks() + Drag()``; its
  own timers split each step into our force phase (bulk read, sub-step plan,
  kicks, bulk write) and Chipmunk's ``space.step`` calls (which include the
  compiled callbacks of the collision rule). The overhead ratio is total / ``space.step``:
  what our forces add to the pymunk work of the *same* configuration.
* ``bare``: the same start stepped with no forces. It is not the same workload:
  without attraction the packed film relaxes and keeps about a third of its
  contacts, so it is shown for reference only.

Also: begin callbacks per step, contacts per dot, Verlet-list rebuilds per 100
steps, and the worst overlap (r_i + r_j - d) / mean radius after the timed steps.
Log-log fits give the growth exponents in N (the scaling plot of ``run``: 300 to 100,000 dots).

Run: ``python -m benchmarks.engine_overhead [--sizes 300 3000 30000] [--steps 200]``
"""

from __future__ import annotations

import argparse
import platform

import numpy as np
import pymunk
from matplotlib.figure import Figure as MplFigure
from scipy.spatial import cKDTree

import qdots
from qdots.analysis import overlaps
from qdots.engine.allocator import tune_allocator

from . import pinned
from .report import Figure, Headline, Note, Table
from .staleness import CHIPMUNK_ENGINE

#: The code this benchmark measures (besides itself): a commit to it after a run marks the run's section as
#: older than its code (`benchmarks.staleness`).
MEASURED_CODE = (*CHIPMUNK_ENGINE, "qdots/forces", "qdots/geometry", "qdots/simulation.py", "benchmarks/pinned.py")

#: The time step measured, ms.
DT_MS = 1e3 * pinned.CHIPMUNK.dt
#: Sizes of the scaling run (``run``), full and quick.
SIZES = {False: [300, 1000, 3000, 10000, 30000, 100000], True: [300, 1000, 3000]}


def initial_positions(n: int, kind: str, rng: np.random.Generator) -> tuple[np.ndarray, tuple[float, float]]:
    """``"loose"``: square lattice, 17 px pitch, jittered; ``"packed"``: hexagonal, 15.02 px pitch."""
    side = int(np.ceil(np.sqrt(n)))
    ij = np.argwhere(np.ones((side, side)))[:n].astype(float)
    if kind == "loose":
        positions = 20.0 + 17.0 * ij + rng.uniform(-0.9, 0.9, (n, 2))
        return positions, (17.0 * side + 40.0,) * 2
    pitch = 15.02
    x = 20.0 + pitch * (ij[:, 1] + 0.5 * (ij[:, 0] % 2))
    y = 20.0 + pitch * np.sqrt(3) / 2 * ij[:, 0]
    return np.column_stack([x, y]), (pitch * side + 60.0,) * 2


def warm_scene(n: int, kind: str, seed: int = 0, warmup_s: float = 0.3) -> qdots.Scene:
    """n dots of 15 px laid out as ``kind``, run under the full force set until contacts form."""
    positions, box = initial_positions(n, kind, np.random.default_rng(seed))
    scene = qdots.Scene(box=box, positions=positions, radii=np.full(n, 7.5))
    sim = qdots.Simulation(scene, full_forces(), seed=seed, engine=pinned.CHIPMUNK)
    state = sim.run(warmup_s)
    return scene.replace(positions=state.positions, velocities=state.velocities, overlap_tolerance=0.05)


def full_forces() -> list[qdots.Force]:
    """van der Waals + thermal kicks + drag."""
    return [qdots.VanDerWaals(), qdots.ThermalKicks(), qdots.Drag()]


def pair_rebuilds(sim: qdots.Simulation) -> int:
    """Rebuilds so far of the van der Waals pair list of ``sim`` (its first force)."""
    return sim.force_cache(sim.forces[0])["pairs"].rebuilds


def measure(n: int, kind: str, steps: int, chunk: int = 20, warmup_s: float = 0.3) -> dict:
    scene = warm_scene(n, kind, warmup_s=warmup_s)
    full = qdots.Simulation(scene, full_forces(), seed=1, engine=pinned.CHIPMUNK)
    bare = qdots.Simulation(scene, [], seed=1, engine=pinned.CHIPMUNK)
    sims = (full, bare)
    for sim in sims:
        sim.step(chunk)  # first list build outside the timing
        sim.timings.update(forces=0.0, pymunk=0.0)
    rebuilds0, begins0, substeps0 = pair_rebuilds(full), full.collisions.dot_dot, full.substeps_taken
    rounds = max(1, steps // chunk)
    for _ in range(rounds):  # alternate, so drifts in machine speed hit all alike
        for sim in sims:
            sim.step(chunk)
    done = rounds * chunk
    ms = {name: 1e3 * t / done for name, t in full.timings.items()}
    return {
        "N": n,
        "scene": kind,
        "full_ms": ms["forces"] + ms["pymunk"],
        "pymunk_ms": ms["pymunk"],
        "forces_ms": ms["forces"],
        "ratio": (ms["forces"] + ms["pymunk"]) / ms["pymunk"],
        "substeps_per_step": (full.substeps_taken - substeps0) / done,
        "s_per_simulated_s": (ms["forces"] + ms["pymunk"]) / (1e3 * full.dt),
        "begins_per_step": (full.collisions.dot_dot - begins0) / done,
        "bare_ms": 1e3 * bare.timings["pymunk"] / done,
        "rebuilds_per_100": 100.0 * (pair_rebuilds(full) - rebuilds0) / done,
        "overlap_pct": 100.0 * overlaps(full.state())[0],
        "contacts_per_dot": contacts_per_dot(full.state()),
        "bare_contacts_per_dot": contacts_per_dot(bare.state()),
    }


def contacts_per_dot(state: qdots.State, tol: float = 0.05) -> float:
    pairs = cKDTree(state.positions).query_pairs(2 * state.radii.max() + tol, output_type="ndarray")
    return 2.0 * len(pairs) / state.n_dots


COLUMNS = ["scene", "N", "total ms/step", "wall s per simulated s", "Chipmunk sub-steps per step", "pymunk step",
           "our forces + I/O", "overhead total/pymunk",
           "impacts /step", "contacts/dot", "list rebuilds /100 steps", "worst overlap (% r)",
           "bare: no forces, same start (ms, contacts/dot)"]


def table(rows: list[dict]) -> Table:
    return Table(
        f"Cost per step (dt = {DT_MS:g} ms, VanDerWaals + ThermalKicks + Drag, pinned settings) and worst overlap "
        "after the timed steps",
        COLUMNS,
        [[r["scene"], r["N"], r["full_ms"], r["s_per_simulated_s"], r["substeps_per_step"], r["pymunk_ms"],
          r["forces_ms"], f"{r['ratio']:.2f}x",
          round(r["begins_per_step"]), r["contacts_per_dot"], r["rebuilds_per_100"], r["overlap_pct"],
          f"{r['bare_ms']:.2f} ms, {r['bare_contacts_per_dot']:.2f}"] for r in rows])


def exponents(rows: list[dict], kind: str) -> dict[str, float]:
    """Log-log slopes of total, force-phase and pymunk cost against N for one scene kind."""
    group = [r for r in rows if r["scene"] == kind]
    if len(group) < 2:
        return {}
    ns = np.log([r["N"] for r in group])
    return {key: float(np.polyfit(ns, np.log([r[key] for r in group]), 1)[0])
            for key in ("full_ms", "forces_ms", "pymunk_ms")}


def fit_lines(rows: list[dict]) -> str:
    lines = []
    for kind in sorted({r["scene"] for r in rows}):
        fit = exponents(rows, kind)
        if fit:
            lines.append(f"{kind}: total step cost grows as N^{fit['full_ms']:.2f} "
                         f"(our forces N^{fit['forces_ms']:.2f}, pymunk N^{fit['pymunk_ms']:.2f})")
    return "\n".join(lines)


def scaling_figure(rows: list[dict]) -> MplFigure:
    fig = MplFigure(figsize=(6.4, 4.2))
    ax = fig.add_subplot()
    for kind, colour in (("packed", "C0"), ("loose", "C1")):
        group = [r for r in rows if r["scene"] == kind]
        if not group:
            continue
        n = np.array([r["N"] for r in group], float)
        for key, style, label in (("full_ms", "o-", "total"), ("forces_ms", "s--", "our forces + I/O"),
                                  ("pymunk_ms", "^:", "pymunk step")):
            ms = np.array([r[key] for r in group])
            slope = exponents(rows, kind).get(key, float("nan"))
            ax.loglog(n, ms, style, color=colour, label=f"{kind}, {label} (N^{slope:.2f})")
    ax.set_xlabel("dots N")
    ax.set_ylabel(f"ms per step (dt = {DT_MS:g} ms)")
    ax.set_title("qdots cost per step against N")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    return fig


def run(quick: bool) -> list:
    """Both scenes at every size of `SIZES`; table, scaling plot and fitted exponents."""
    rows = []
    for kind in ("packed", "loose"):
        for n in SIZES[quick]:
            # the largest boards get fewer timed steps, and the packed ones (touching from the start) a shorter
            # warm-up: a 100,000-dot packed step takes ~0.2 s
            big = n > 10000
            rows.append(measure(n, kind, steps=40 if quick else (40 if big else 200), chunk=10 if big else 20,
                                warmup_s=0.05 if big and kind == "packed" else 0.3))
    packed = exponents(rows, "packed")
    at_3000 = next(r for r in rows if r["scene"] == "packed" and r["N"] == 3000)
    largest = max((r for r in rows if r["scene"] == "packed"), key=lambda r: r["N"])
    return [
        Headline(f"qdots step, 3,000 packed dots, vdW + kicks + drag (dt {DT_MS:g} ms)",
                 f"{at_3000['full_ms']:.2f} ms/step ({at_3000['s_per_simulated_s']:.2f} s per simulated s)",
                 f"worst overlap {at_3000['overlap_pct']:.2f} % of r"),
        Headline(f"qdots scaling, packed film, {SIZES[quick][0]:,} to {largest['N']:,} dots",
                 f"N^{packed['full_ms']:.2f}; {largest['full_ms']:.0f} ms/step at {largest['N']:,}",
                 f"worst overlap {largest['overlap_pct']:.2f} % of r"),
        table(rows),
        Note(fit_lines(rows) + f" (fit over N = {SIZES[quick][0]:,} to {SIZES[quick][-1]:,}). `total/pymunk` is "
             "what our forces add to Chipmunk's own work on the same configuration; `bare` is the same start "
             "with no forces (a different workload: without attraction the packed film relaxes). At the 20 ms "
             "frame every van der Waals pair is pulled every frame (the thesis's model); the split of the pull "
             "into near pairs every step and far pairs every `far_interval` (not the default) is measured in "
             "`qdots_knobs`."),
        Figure("qdots_scaling", scaling_figure(rows),
               "qdots ms/step against N, packed (hexagonal, settled) and loose (square lattice) films, with "
               "the fitted exponents."),
    ]


def machine() -> str:
    """The machine and versions; whether the allocator was tuned (the cached result of the call the simulations
    built before made, `qdots.Chipmunk.tune_allocator`)."""
    import os

    return (f"python {platform.python_version()}, pymunk {pymunk.version}, numpy {np.__version__}, "
            f"{os.cpu_count()} cores, {platform.machine()}, allocator tuned: {tune_allocator()}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[300, 3000, 30000])
    parser.add_argument("--scenes", nargs="+", default=["loose", "packed"], choices=["loose", "packed"])
    parser.add_argument("--steps", type=int, default=200)
    args = parser.parse_args(argv)
    rows = [measure(n, kind, args.steps) for kind in args.scenes for n in args.sizes]
    print(machine())
    print(f"dt = {DT_MS:g} ms, defaults: {qdots.VanDerWaals()!r} + ThermalKicks + Drag\n")
    print(table(rows).markdown())
    print("\n" + fit_lines(rows))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
