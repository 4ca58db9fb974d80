"""qdots error against time, one curve per engine knob, defaults checked against the Pareto front.

Knobs of the Chipmunk engine: time step ``dt``, the sub-steps' ``overlap_tolerance`` (and fixed sub-steps),
Chipmunk ``substeps`` and solver ``iterations``, ``collision_slop``, overlap correction per step
(``collision_bias``), the van der Waals pair list's Verlet skin (``pair_skin``), the far pass of the van der
Waals pull (``far_interval``, with the pairs closer than ``near_gap`` pulled every step), and Chipmunk's spatial
hash against its default bounding-box tree. Each knob is swept over the test problems it can affect
(`benchmarks.qdots_cases`: isolated restitution, elastic-gas energy, two-body vdW against the thesis's frames,
worst overlap in a dense pack, pair list against brute force, the split vdW impulse against every pair every
step), every other knob at the pinned settings (`benchmarks.pinned.CHIPMUNK`, the defaults of 0.3.0: the thesis's
20 ms frame). The library's default of each knob is starred; a setting that is not the library's default any
more is not starred, and the verdict says so. Settings are run in turn, ``repeats`` times (cost: the fastest; a
run shorter than `MIN_WALL` is repeated until that much wall time is spent), so drifts in machine speed hit them
alike. Cost is wall seconds per simulated second of the same run that gave the error. The Pareto rule is
`benchmarks.pareto`.

``dt`` is swept on the cases without the van der Waals pull only, and on the packs' overlap: the thesis's proxy
is a velocity change per frame, so another frame is another model of the pull (docs/engines.md), not a finer
approximation of the same one. ``near_gap`` acts only with ``far_interval`` set, which the default is not.

Run: ``python -m benchmarks.qdots_knobs [--quick] [--figures DIR]``
"""

from __future__ import annotations

import math
import textwrap
import time

from matplotlib.figure import Figure as MplFigure

from . import pareto, pinned
from .qdots_cases import CASES
from .report import Figure, Headline, Note, Table, cli
from .staleness import CHIPMUNK_ENGINE

#: The code this benchmark measures (besides itself): a commit to it after a run marks the run's section as
#: older than its code (`benchmarks.staleness`).
MEASURED_CODE = (*CHIPMUNK_ENGINE,
                 "qdots/forces", "qdots/geometry", "qdots/simulation.py", "benchmarks/qdots_cases.py",
                 "benchmarks/pareto.py", "benchmarks/pinned.py")


def _bias(fraction: float) -> float:
    """pymunk's collision_bias that corrects ``fraction`` of an overlap per sub-step as long as the pinned dt."""
    return (1.0 - fraction) ** (1.0 / pinned.CHIPMUNK.dt)


#: knob -> (what it is, [(label, settings changed from the pinned ones, full, quick)], cases).
KNOBS = {
    "dt": ("time step (the frame)", [("20 ms", {}, True, True), ("10 ms", {"dt": 1e-2}, True, False),
                                     ("5 ms", {"dt": 5e-3}, True, True), ("2.5 ms", {"dt": 2.5e-3}, True, True),
                                     ("1 ms", {"dt": 1e-3}, True, False)],
           ["restitution", "gas_energy", "pack_g1", "pack_g10"]),
    "overlap_tolerance": ("largest travel into a contact per Chipmunk sub-step (radii); fixed: never split", [
        ("fixed", {"overlap_tolerance": None}, True, True), ("0.02", {"overlap_tolerance": 0.02}, True, False),
        ("0.01", {"overlap_tolerance": 0.01}, True, True), ("0.005", {}, True, True),
        ("0.0025", {"overlap_tolerance": 0.0025}, True, False)],
        ["restitution", "gas_energy", "pack_g1", "pack_g10"]),
    "substeps": ("fewest Chipmunk steps per time step; grey: the dt curve", [
        ("1", {}, True, True), ("2", {"substeps": 2}, True, True), ("4", {"substeps": 4}, True, True),
        ("8", {"substeps": 8}, True, False)], ["restitution", "gas_energy", "pack_g1", "pack_g10"]),
    "iterations": ("solver iterations per sub-step", [
        ("3", {"iterations": 3}, True, False), ("5", {}, True, True), ("10", {"iterations": 10}, True, True),
        ("20", {"iterations": 20}, True, True), ("40", {"iterations": 40}, True, False)],
        ["gas_energy", "pack_g1", "pack_g10"]),
    "collision_slop": ("overlap left uncorrected (px)", [
        ("0.001", {"collision_slop": 0.001}, True, False), ("0.01", {}, True, True),
        ("0.1 (pymunk)", {"collision_slop": 0.1}, True, True), ("0.5", {"collision_slop": 0.5}, True, False)],
        ["gas_energy", "pack_g1", "pack_g10"]),
    "collision_bias": ("overlap corrected per sub-step (collision_bias for sub-steps of 20 ms)", [
        ("10 %", {"collision_bias": _bias(0.1)}, True, True), ("20 %", {"collision_bias": _bias(0.2)}, True, False),
        ("30 %", {}, True, True), ("50 %", {"collision_bias": _bias(0.5)}, True, True)],
        ["pack_g1", "pack_g10"]),
    "pair_skin": ("Verlet skin of the vdW pair list (px)", [
        ("0", {"pair_skin": 0.0}, True, True), ("1", {"pair_skin": 1.0}, True, False),
        ("3", {"pair_skin": 3.0}, True, True), ("6", {}, True, True), ("12", {"pair_skin": 12.0}, True, False)],
        ["list_pack", "list_film", "vdw_pair"]),
    "far_interval": ("seconds between the vdW far passes (pairs closer than near_gap = 4 px every step)", [
        ("every step", {}, True, True), ("40 ms", {"far_interval": 0.04}, True, True),
        ("100 ms", {"far_interval": 0.1}, True, False),
        ("40 ms, near_gap 8 px", {"far_interval": 0.04, "near_gap": 8.0}, True, False)],
        ["vdw_pair", "vdw_far", "split_pack", "split_film"]),
    "spatial_index": ("Chipmunk's bounding-box tree against its spatial hash (cell px, count 10 N)", [
        ("tree", {}, True, True), ("hash 8", {"spatial_hash": (8.0, 10000)}, True, False),
        ("hash 16", {"spatial_hash": (16.0, 10000)}, True, True), ("hash 32", {"spatial_hash": (32.0, 10000)}, True, False)],
        ["gas_energy", "pack_g1", "pack_g10"]),
}


#: Wall seconds each (setting, case) measurement is repeated for, at least once: the two-body cases run
#: for a few ms, where one timing is mostly noise.
MIN_WALL = 0.25


def is_default(settings: dict) -> bool:
    """True when the pinned settings with these changes are the library's defaults."""
    return pinned.is_library_default(pinned.chipmunk(**settings))


def sweep(knob: str, quick: bool, repeats: int) -> dict[str, list[pareto.Point]]:
    """Points (label, cost, error) of every setting of ``knob`` on each of its cases."""
    _, settings, cases = KNOBS[knob]
    chosen = [(label, s) for label, s, full, short in settings if (short if quick else full)]
    points = {case: [pareto.Point(label, math.inf, math.nan, is_default(s)) for label, s in chosen] for case in cases}
    for _ in range(repeats):
        for case in cases:
            measure = CASES[case][3]
            for point, (_label, s) in zip(points[case], chosen):
                start = time.perf_counter()
                while True:  # a run of a few ms is timed again, its fastest kept
                    m = measure(s, quick)
                    point.time = min(point.time, m.cost)
                    if quick or time.perf_counter() - start >= MIN_WALL:
                        break
                if math.isnan(point.error):
                    point.error, point.error_se = m.error, m.error_se
    return points


def knob_figure(knob: str, points: dict[str, list[pareto.Point]], dt_points: dict) -> MplFigure:
    cases = list(points)
    cols = min(3, len(cases))
    rows = math.ceil(len(cases) / cols)
    fig = MplFigure(figsize=(4.0 * cols, 3.4 * rows), layout="constrained")
    for k, case in enumerate(cases):
        title, ylabel, floor, _ = CASES[case]
        ax = fig.add_subplot(rows, cols, k + 1)
        reference = dt_points.get(case, []) if knob == "substeps" else []
        pareto.plot(ax, points[case], title=textwrap.fill(title, 45), xlabel="wall s per simulated s",
                    ylabel=ylabel, floor=floor, reference=reference, reference_label="dt 10 ... 1 ms")
    fig.suptitle(f"{knob}: {KNOBS[knob][0]}", fontsize=10)
    return fig


def knob_table(knob: str, points: dict[str, list[pareto.Point]]) -> Table:
    rows = []
    for case, pts in points.items():
        floor = CASES[case][2]
        for p in pts:
            error = f"{p.error:.2e}" + (f" +- {p.error_se:.1e}" if p.error_se else "")
            rows.append([CASES[case][0], p.label + (" (default)" if p.default else ""), p.time * 1e3,
                         error, pareto.verdict(pts, floor) if p.default else ""])
    return Table(f"{knob}: {KNOBS[knob][0]}",
                 ["case", "setting", "cost (ms wall per simulated s)", "error", "default vs the front"], rows)


def run(quick: bool) -> list:
    repeats = 1 if quick else 2
    results, verdicts, curves = [], [], []
    dt_points: dict = {}
    for knob in KNOBS:
        points = sweep(knob, quick, repeats)
        if knob == "dt":
            dt_points = {case: [p for p in pts if p.label != "20 ms"] for case, pts in points.items()}
        results.append(knob_table(knob, points))
        results.append(Figure(f"qdots_knob_{knob}", knob_figure(knob, points, dt_points),
                              f"{knob}: error against wall time per simulated second for each case; the red star "
                              f"is the default; each subplot's title says whether it is on the Pareto front."))
        for case, pts in points.items():
            verdicts.append((knob, case, pareto.verdict(pts, CASES[case][2])))
            curves.append((knob, case, pts))
    off = [(k, c, v) for k, c, v in verdicts if v != "on the front"]
    summary = (f"Defaults on the Pareto front in {len(verdicts) - len(off)} of {len(verdicts)} (knob, case) curves."
               + ("" if not off else " Not on it: " + "; ".join(f"**{k}** / {CASES[c][0]}: {v}" for k, c, v in off)
                  + "."))
    dt_curves = {case: pts for knob, case, pts in curves if knob == "dt"}
    default = {case: next((p for p in pts if p.default), pts[0]) for case, pts in dt_curves.items()}
    vdw = next(p for knob, case, pts in curves if knob == "pair_skin" and case == "vdw_pair" for p in pts
               if p.label == "6")
    moved = pinned.moved_defaults()
    if moved:
        summary += " The library's defaults have moved from the settings measured here: " + "; ".join(moved) + "."
    return [
        Headline("qdots defaults, dense pack under centre gravity x1 / x10",
                 f"{default['pack_g1'].time:.2f} / {default['pack_g10'].time:.2f} s wall per simulated s",
                 f"worst overlap {100 * default['pack_g1'].error:.2f} / {100 * default['pack_g10'].error:.2f} % of r"),
        Headline("qdots defaults, isolated impact / elastic gas / two-body vdW",
                 f"{1e3 * default['gas_energy'].time:.0f} ms per simulated s (gas)",
                 f"velocity {default['restitution'].error:.1e} of v_rel; energy {default['gas_energy'].error:.1e}; "
                 f"position {vdw.error:.1e} px"),
        Headline(f"qdots defaults against the Pareto front of {len(KNOBS)} knobs",
                 f"{len(verdicts) - len(off)} of {len(verdicts)} curves on the front",
                 "; ".join(f"{k} on {CASES[c][0]}" for k, c, _ in off) or "none off"),
        Note(summary),
    ] + results


def main(argv: list[str] | None = None) -> int:
    return cli(run, __doc__.splitlines()[0], argv)


if __name__ == "__main__":
    raise SystemExit(main())
