"""Board analysis at 10^5 dots: time of each measure, and its error against exact answers and freud.

Two boards of ~100,000 dots of 15 px:

* ``flake``: a perfect hexagonal flake of ``s`` rings (``3 s (s + 1) + 1`` dots) whose every number
  is known: interior fraction ``1 - 6 s / N``, 6 neighbours per interior dot, psi6 = 1, Voronoi
  coordination 6 for every bounded cell, one cluster, ``3 s (3 s + 1)`` pairs at contact.
* ``disordered``: the same flake with 10 % of the dots removed at random and every dot moved by
  up to +-1.5 px (equal radii): neighbour counts and psi6 are compared with freud (if installed;
  freud computes in single precision).

Each measure is timed separately; ``total`` is `packing_summary` + hexatic order + clusters +
Voronoi coordination + g(r) (5 diameters, 100 bins) + fill within 20 radii. Goal: < 2 s.

Run: ``python -m benchmarks.analysis [--rings 182]``
"""

from __future__ import annotations

import argparse
import time
from types import SimpleNamespace

import numpy as np

from qdots.analysis import fill_within_radius, neighbour_counts, packing_summary
from qdots.analysis.structure import clusters, hexatic_order, radial_distribution, voronoi_coordination
from qdots.placement import hexagonal_lattice

from .report import Headline, Table, cli_with_options

#: The code this benchmark measures (besides itself): a commit to it after a run marks the run's section as
#: older than its code (`benchmarks.staleness`).
MEASURED_CODE = ("qdots/analysis", "qdots/geometry")

DIAMETER = 15.0


def flake(rings: int) -> SimpleNamespace:
    xy = hexagonal_lattice(rings, DIAMETER, "flake")
    side = 2 * (rings + 2) * DIAMETER
    return SimpleNamespace(positions=xy + side / 2, radii=np.full(len(xy), DIAMETER / 2), box=(side, side))


def measure(board) -> tuple[dict, dict]:
    times, out = {}, {}

    def run(name, fn, *args, **kwargs):
        start = time.perf_counter()
        out[name] = fn(*args, **kwargs)
        times[name] = time.perf_counter() - start

    run("packing_summary", packing_summary, board)
    run("hexatic", hexatic_order, board)
    run("clusters", clusters, board)
    run("voronoi", voronoi_coordination, board)
    run("rdf", radial_distribution, board, r_max=5 * DIAMETER, bins=100)
    run("fill", fill_within_radius, board, np.linspace(0.025, 0.5, 20) * board.box[0])
    return times, out


def flake_errors(rings: int, out: dict) -> dict:
    n = 3 * rings * (rings + 1) + 1
    summary, vor = out["packing_summary"], out["voronoi"]
    rdf = out["rdf"]
    contact = rdf.counts[(rdf.r > 0.9 * DIAMETER) & (rdf.r < 1.1 * DIAMETER)].sum()  # next shell: sqrt(3) d
    return {
        "interior fraction": abs(summary["interior_fraction"] - (n - 6 * rings) / n),
        "mean neighbours (interior)": abs(summary["mean_neighbours_interior"] - 6.0),
        "psi6 global": abs(out["hexatic"].global_order - 1.0),
        "Voronoi coordination": float(np.abs(vor[vor >= 0] - 6).max()),
        "clusters": abs(len(out["clusters"][1]) - 1),
        "g(r) contact pairs": abs(int(contact) - 3 * rings * (3 * rings + 1)),
    }


def freud_errors(board) -> dict:
    try:
        import freud
    except ImportError:
        return {"freud": "not installed"}
    pts = np.zeros((len(board.positions), 3))
    pts[:, :2] = board.positions - np.asarray(board.box) / 2
    box = freud.box.Box.square(2 * max(board.box))
    nlist = freud.locality.AABBQuery(box, pts).query(pts, dict(r_max=1.5 * DIAMETER, exclude_ii=True)).toNeighborList()
    hexatic = freud.order.Hexatic(k=6)
    hexatic.compute((box, pts), neighbors=nlist)
    ours = hexatic_order(board)
    return {
        "neighbour counts differing from freud": int((neighbour_counts(board) != nlist.neighbor_counts).sum()),
        "max |psi6 - freud psi6|": float(np.abs(ours.psi - hexatic.particle_order)[ours.has_neighbours].max()),
    }


def results(rings: int, seed: int = 1) -> list:
    perfect = flake(rings)
    rng = np.random.default_rng(seed)
    keep = rng.random(len(perfect.radii)) > 0.1
    disordered = SimpleNamespace(positions=perfect.positions[keep] + rng.uniform(-1.5, 1.5, (keep.sum(), 2)),
                                 radii=perfect.radii[keep], box=perfect.box)
    rows = []
    for name, board in (("flake", perfect), ("disordered", disordered)):
        times, out = measure(board)
        errors = flake_errors(rings, out) if name == "flake" else freud_errors(board)
        rows.append((name, len(board.radii), times, errors))
    names = list(rows[0][2])
    flake_total = sum(rows[0][2].values())
    worst = max(v for v in rows[0][3].values())
    return [
        Headline(f"full board analysis (6 measures), {rows[0][1]:,} dots", f"{flake_total:.2f} s",
                 f"largest error against exact lattice values {worst:.1g}"),
        Table("Time of each measure (s); goal < 2 s in total",
              ["board", "N", *names, "total (s)", "goal < 2 s"],
              [[name, n, *(times[k] for k in names), sum(times.values()),
                "met" if sum(times.values()) < 2 else "NOT met"] for name, n, times, _ in rows]),
        Table("Errors in the same runs", ["board", "quantity", "error"],
              [[name, key, value] for name, _, _, errors in rows for key, value in errors.items()]),
    ]


def run(quick: bool) -> list:
    """Every measure on a 100,000-dot board (quick: 11,000 dots) against exact values and freud."""
    return results(60 if quick else 182)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rings", type=int, default=182, help="rings of the flake (182: 99,919 dots)")
    parser.add_argument("--seed", type=int, default=1)
    return cli_with_options(parser, lambda args: results(args.rings, args.seed), argv)


if __name__ == "__main__":
    raise SystemExit(main())
