"""Reference-engine cost on the thesis hill and larger hills: the baseline the fast engine must beat.

Cases: the thesis hill (5 x 5 points at 1 nm, centre 4.5 nm, refined 4x: 17 x 17 at 0.25 nm)
and the same hill on larger samples at the same resolution, 9 x 9 and 17 x 17 points refined 4x
(33 x 33 and 65 x 65 at 0.25 nm; the hill fills a smaller part of them). Each is oxidized to 1 nm
in 0.01 nm steps, k_exp 2.3, thesis distances, exact volume accounting.

For each case, in the same run:

* the reference engine (the thesis algorithm), stopped after ``--budget`` seconds if unfinished:
  wall time, oxide thickness reached, metal-point updates per second, and the volume balance
  error (oxide gained / ((k_exp - 1) metal lost) - 1; exact accounting makes it round-off);
* the fast engine at its default batch tolerance (a tenth of a step) and at tolerance 0 (exact ties only):
  wall time, and the largest difference of its metal and oxide RMS from the reference's at the
  recorded thicknesses (every 0.1 nm the reference reached).

An unfinished reference run's full time is extrapolated at its measured update rate to the
number of updates the tolerance-0 fast engine needed (the two take the same steps: checked on
the cases that finish). The rate is steady over a run: stopped after 8 s at 0.25 nm, the 17 x 17
hill extrapolates to 37.4 s; run to the end it took 37.0 s.

Run: ``python -m benchmarks.planarize_reference [--sizes 17 33 65] [--budget 600] [--csv FILE]``
"""

from __future__ import annotations

import argparse
import platform
from pathlib import Path

import numpy as np

import planarize
from labrig.files import write_csv
from planarize import Model

from .report import Headline, Table

#: The code this benchmark measures (besides itself): a commit to it after a run marks the run's section as
#: older than its code (`benchmarks.staleness`).
MEASURED_CODE = ("planarize",)

THICKNESS, STEP, K_EXP = 1.0, 0.01, 2.3
#: Grid side -> grid points per side of the hill before the 4x refinement.
SIZES = {17: 5, 33: 9, 65: 17}
RECORD = np.linspace(0.0, THICKNESS, 11)


def reference(metal: planarize.Surface, budget: float) -> dict:
    """Run the reference engine until the target or the time budget; history rows at `RECORD`."""
    run = planarize.anodize(metal, THICKNESS, Model(step=STEP, k_exp=K_EXP), "reference", record=RECORD,
                            max_seconds=budget)
    rows = run.rows()
    final = rows[-1]
    return {"rows": rows if run.complete else rows[:-1], "final": final, "finished": run.complete}


def rms_difference(rows: list[dict], history: dict) -> float:
    """Largest |RMS difference| (metal and oxide) at the reference's recorded thicknesses, nm."""
    worst = 0.0
    for k, row in enumerate(rows):
        for key in ("metal_rms_nm", "oxide_rms_nm"):
            worst = max(worst, abs(row[key] - float(history[key][k])))
    return worst


def measure(side: int, budget: float) -> dict:
    metal = planarize.surfaces.hill(points=SIZES[side], refine=4)
    ref = reference(metal, budget)
    model = Model(step=STEP, k_exp=K_EXP)
    fast = planarize.anodize(metal, THICKNESS, model, "fast", record=RECORD)
    exact_ties = planarize.anodize(metal, THICKNESS, model, planarize.Fast(tolerance=0.0), record=RECORD)
    final = ref["final"]
    rate = final["point_updates"] / final["wall_s"]
    total_updates = int(exact_ties.history["point_updates"][-1])
    return {
        "grid": f"{side} x {side}",
        "points": side * side,
        "reference_s": round(final["wall_s"], 2),
        "reached_nm": round(final["thickness_nm"], 4),
        "finished": ref["finished"],
        "updates": final["point_updates"],
        "updates_per_s": round(rate, 1),
        "reference_full_s": round(final["wall_s"] if ref["finished"] else total_updates / rate, 1),
        "same_updates_as_tol0": final["point_updates"] == total_updates if ref["finished"] else "",
        "volume_error": final["volume_error"],
        "fast_s": round(fast.wall_s, 3),
        "fast_speedup": round((final["wall_s"] if ref["finished"] else total_updates / rate) / fast.wall_s, 1),
        "fast_max_drms_nm": rms_difference(ref["rows"], fast.history),
        "fast_volume_error": float(fast.history["volume_error"][-1]),
        "tol0_s": round(exact_ties.wall_s, 3),
        "tol0_max_drms_nm": rms_difference(ref["rows"], exact_ties.history),
        "compared_to_nm": float(RECORD[len(ref["rows"]) - 1]),
    }


def table(rows: list[dict]) -> Table:
    return Table(
        f"Hill to {THICKNESS:g} nm, step {STEP:g} nm, k_exp {K_EXP:g}: reference engine against the fast engine",
        ["grid", "reference (s)", "reached (nm)", "updates/s", "full run (s)", "volume error", "fast (s)", "speed-up",
         "fast max dRMS (nm)", "tol 0 (s)", "tol 0 max dRMS (nm)", "compared to (nm)"],
        [[r["grid"], r["reference_s"], f"{r['reached_nm']:.3f}", round(r["updates_per_s"]),
          f"{r['reference_full_s']:.1f}" + ("" if r["finished"] else " (extrapolated)"), f"{r['volume_error']:.1e}",
          r["fast_s"], f"{r['fast_speedup']:.0f}x", f"{r['fast_max_drms_nm']:.1e}", r["tol0_s"],
          f"{r['tol0_max_drms_nm']:.1e}", f"{r['compared_to_nm']:.1f}"] for r in rows])


def run(quick: bool) -> list:
    """17 x 17 and 33 x 33 hills, reference stopped after 120 s (quick: 17 x 17, 5 s) and extrapolated."""
    rows = [measure(side, 5.0 if quick else 120.0) for side in ((17,) if quick else (17, 33))]
    first = rows[0]
    return [Headline(f"planarize fast engine, {first['grid']} hill to {THICKNESS:g} nm",
                     f"{first['fast_s']:.2f} s ({first['fast_speedup']:.0f}x the reference engine)",
                     f"max RMS difference from the reference {first['fast_max_drms_nm']:.0e} nm, "
                     f"volume error {first['fast_volume_error']:.0e}"),
            table(rows)]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=list(SIZES), choices=list(SIZES),
                        help="grid sides to run (default 17 33 65)")
    parser.add_argument("--budget", type=float, default=600.0,
                        help="seconds the reference engine may run per case (default 600)")
    parser.add_argument("--csv", type=Path, default=Path("planarize_reference.csv"),
                        help="table written here too (default ./planarize_reference.csv)")
    args = parser.parse_args(argv)
    print(f"python {platform.python_version()}, numpy {np.__version__}, {platform.machine()}; "
          f"hill to {THICKNESS:g} nm, step {STEP:g} nm, k_exp {K_EXP:g}, reference budget {args.budget:g} s\n")
    rows = []
    for side in args.sizes:
        rows.append(measure(side, args.budget))
        r = rows[-1]
        print(f"  {r['grid']}: reference {r['reference_s']:.1f} s to {r['reached_nm']:.3f} nm, "
              f"fast {r['fast_s']:.2f} s, tolerance 0 {r['tol0_s']:.2f} s", flush=True)
    print("\n" + table(rows).markdown())
    checked = [r for r in rows if r["finished"]]
    if checked:
        print(f"\nreference and tolerance-0 fast engine take the same number of updates: "
              f"{all(r['same_updates_as_tol0'] for r in checked)} ({len(checked)} finished case(s))")
    print(f"wrote {write_csv(args.csv, rows)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
