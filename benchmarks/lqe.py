"""LQE speed against error: exact solve at 10^3-10^5 dots, Gillespie and thesis Monte Carlo rates, dt bias.

Boards are close-packed hexagonal films of 15 px dots (the thesis's Fig 2-5 setting), R_F = one
diameter, 1/3 traps (seed 1).

* ``exact``: `exciton_network` (KD-tree pairs within the cutoff of the default tolerance, sparse
  rates) + `lqe_exact` (conjugate gradients). Errors: the rigorous bound (cutoff + solver residual)
  and the measured change against a longer cutoff (all pairs at 1,000 dots, else one whose bound is
  1e-5 (10,000 dots) or 1e-4 (100,000 dots): memory grows as the cutoff squared).
* ``gillespie`` / ``thesis``: Monte Carlo excitons per second on the 10,000-dot film (same network
  as the exact row), with the standard error and the deviation from the exact value (for the
  thesis method: from the exact law of its own scheme, and its bias against the physical chain).
* ``dt bias``: the thesis scheme's exact expected LQE minus the continuous-time exact LQE, for
  dt = tau/10 ... tau/1000, at R_F = 1 and 2 diameters (no sampling noise).

Run: ``python -m benchmarks.lqe [--sizes 1000 10000 100000] [--excitons 1000000]``
"""

from __future__ import annotations

import argparse
import math
import time
from types import SimpleNamespace

import numpy as np

from qdots.analysis.forster import TAU_NS, exciton_network
from qdots.analysis.lqe import lqe_exact, lqe_monte_carlo
from qdots.placement import hexagonal_lattice

from .report import Headline, Table, cli_with_options

#: The code this benchmark measures (besides itself): a commit to it after a run marks the run's section as
#: older than its code (`benchmarks.staleness`).
MEASURED_CODE = ("qdots/analysis",)

DIAMETER = 15.0


def hex_film(n: int) -> SimpleNamespace:
    """About ``n`` touching dots on a square-ish patch of a hexagonal lattice."""
    m = int(round(math.sqrt(n)))
    return SimpleNamespace(positions=hexagonal_lattice(m, DIAMETER, origin=(DIAMETER, DIAMETER)),
                           radii=np.full(m * m, DIAMETER / 2))


def timed(fn, *args, **kwargs):
    start = time.perf_counter()
    out = fn(*args, **kwargs)
    return out, time.perf_counter() - start


def exact_row(n: int) -> dict:
    film = hex_film(n)
    net, t_build = timed(exciton_network, film, seed=1)
    result, t_solve = timed(lqe_exact, net)
    # Reference: all pairs when affordable, else a cutoff 10-100x tighter in bound (memory grows as R_c^2).
    cutoff, tolerance = (1e9, None) if n <= 2000 else (None, 1e-5 if n <= 20000 else 1e-4)
    reference = lqe_exact(exciton_network(film, seed=1, cutoff=cutoff, tolerance=tolerance or 1e-3))
    return {"N": len(film.radii), "partners": net.rates.nnz / len(film.radii), "cutoff": net.cutoff,
            "build": t_build, "solve": t_solve, "lqe": result.lqe, "bound": result.error_bound,
            "measured": abs(result.lqe - reference.lqe),
            "reference": "all pairs" if tolerance is None else f"bound {tolerance:g}, R_c {reference_cutoff(film, tolerance):.0f} px"}


def reference_cutoff(film, tolerance: float) -> float:
    from qdots.analysis.cutoff import cutoff_for

    return cutoff_for(DIAMETER, DIAMETER, tolerance)


def monte_carlo_rows(n: int, excitons: int) -> list[dict]:
    net = exciton_network(hex_film(n), seed=1)
    exact = lqe_exact(net).lqe
    rows = []
    mc, t = timed(lqe_monte_carlo, net, excitons, method="gillespie", seed=2)
    rows.append({"method": "gillespie", "excitons": excitons, "seconds": t, "lqe": mc.lqe, "se": mc.standard_error,
                 "target": exact, "target_name": "exact"})
    few = max(1000, excitons // 20)  # the literal thesis algorithm is much slower per exciton
    mc, t = timed(lqe_monte_carlo, net, few, method="thesis", seed=3)
    thesis_exact = lqe_exact(net, scheme="thesis").lqe
    rows.append({"method": "thesis (dt = tau/100)", "excitons": few, "seconds": t, "lqe": mc.lqe,
                 "se": mc.standard_error, "target": thesis_exact, "target_name": "exact thesis scheme",
                 "bias": thesis_exact - exact})
    return rows


def bias_rows() -> list[dict]:
    rows = []
    film = hex_film(900)
    for diameters in (1.0, 2.0):
        net = exciton_network(film, forster_radius=diameters * DIAMETER, seed=1, cutoff=4 * DIAMETER)
        exact = lqe_exact(net).lqe
        for fraction in (0.1, 0.03, 0.01, 0.003, 0.001):
            thesis, t = timed(lqe_exact, net, scheme="thesis", dt=fraction * TAU_NS)
            rows.append({"R_F": diameters, "dt": fraction, "exact": exact, "thesis": thesis.lqe,
                         "bias": thesis.lqe - exact, "seconds": t})
    return rows


def results(sizes: list[int], excitons: int, mc_size: int = 10_000) -> list:
    exact = [exact_row(n) for n in sizes]
    mc = monte_carlo_rows(mc_size, excitons)
    largest = exact[-1]
    gillespie = mc[0]
    return [
        Headline(f"exact LQE, close-packed film of {largest['N']:,} dots", f"{largest['build'] + largest['solve']:.2f} s",
                 f"bound {largest['bound']:.0e}, measured {largest['measured']:.0e}"),
        Headline(f"Gillespie Monte Carlo LQE, {mc_size:,} dots",
                 f"{gillespie['excitons'] / gillespie['seconds']:,.0f} excitons/s",
                 f"{abs(gillespie['lqe'] - gillespie['target']) / gillespie['se']:.1f} SE from exact"),
        Table("lqe_exact on a close-packed film, R_F = 1 diameter, 1/3 traps, default tolerance 1e-3",
              ["N", "partners/dot", "cutoff (px)", "network (s)", "solve (s)", "total (s)", "LQE", "error bound",
               "measured cutoff error (reference)"],
              [[r["N"], round(r["partners"]), r["cutoff"], r["build"], r["solve"], r["build"] + r["solve"],
                f"{r['lqe']:.5f}", f"{r['bound']:.1e}", f"{r['measured']:.1e} ({r['reference']})"] for r in exact]),
        Table(f"Monte Carlo on the {mc_size:,}-dot film (same network as its exact row)",
              ["method", "excitons", "time (s)", "excitons/s", "LQE +- SE", "|MC - target| / SE (target)",
               "scheme bias vs exact"],
              [[r["method"], r["excitons"], r["seconds"], round(r["excitons"] / r["seconds"]),
                f"{r['lqe']:.4f} +- {r['se']:.4f}", f"{abs(r['lqe'] - r['target']) / r['se']:.2f} ({r['target_name']})",
                f"{r['bias']:+.2e}" if "bias" in r else "0 (no time step)"] for r in mc]),
        Table("Thesis scheme dt bias (exact law of the scheme minus the continuous-time exact LQE), 900 dots",
              ["R_F (diameters)", "dt / tau", "exact LQE", "thesis-scheme LQE", "bias", "relative bias", "time (s)"],
              [[r["R_F"], r["dt"], f"{r['exact']:.5f}", f"{r['thesis']:.5f}", f"{r['bias']:+.2e}",
                f"{r['bias'] / r['exact']:+.1%}", r["seconds"]] for r in bias_rows()]),
    ]


def run(quick: bool) -> list:
    """Exact LQE at 10^3-10^5 dots (quick: 10^3), Monte Carlo rates, the thesis scheme's dt bias."""
    if quick:
        return results([1000], 100_000, mc_size=1000)
    return results([1000, 10000, 100000], 1_000_000)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[1000, 10000, 100000])
    parser.add_argument("--excitons", type=int, default=1_000_000)
    return cli_with_options(parser, lambda args: results(args.sizes, args.excitons), argv)


if __name__ == "__main__":
    raise SystemExit(main())
