"""qdots hard cases (`qdots.diagnostics.hard_cases`): each run and checked, with the time it takes.

Each case runs on the pinned Chipmunk settings (`benchmarks.pinned.CHIPMUNK`, the defaults of 0.3.0) with the
case's own changes; the test suite runs the same cases on the library's current defaults.

Run: ``python -m benchmarks.qdots_hard_cases [--quick]``
"""

from __future__ import annotations

import dataclasses

from qdots.diagnostics.hard_cases import CASES, SAMPLE, HardCase, check, passed

from . import pinned
from .report import Headline, Note, Table, cli
from .staleness import CHIPMUNK_ENGINE

#: The code this benchmark measures (besides itself): a commit to it after a run marks the run's section as
#: older than its code (`benchmarks.staleness`).
MEASURED_CODE = (*CHIPMUNK_ENGINE,
                 "qdots/forces", "qdots/simulation.py", "qdots/diagnostics/hard_cases.py", "benchmarks/pinned.py")


def on_pinned(case: HardCase) -> HardCase:
    """``case`` on the pinned settings, its own changes kept."""
    return dataclasses.replace(case, settings={**pinned.CHIPMUNK.to_dict(), **case.settings})


def run(quick: bool) -> list:
    """Every case (quick: those of the default test suite) with its time and verdict."""
    cases = [c for c in CASES if not (quick and c.slow)]
    rows, failures = [], []
    for case in cases:
        r = check(on_pinned(case))
        ok = passed(r)
        verdict = ("passes" if ok else "FAILS") + (" (known failure)" if case.known_failure else "")
        if ok == bool(case.known_failure):
            failures.append(case.name)
        rows.append([case.name, r["dots"], r["steps"], r["wall_s"], 1e3 * r["wall_s"] / r["steps"],
                     f"{100 * r['overlap']:.3g} (< {100 * r['transient_tolerance']:.3g})",
                     f"{100 * r['settled']:.3g} (< {100 * r['settled_tolerance']:.3g})", "yes" if r["finite"] else "NO",
                     "none" if not (r["lost"] or r["crossed"]) else "YES", "yes" if r["warned"] else "no", verdict])
    known = [c for c in cases if c.known_failure]
    return [
        Headline(f"qdots hard cases ({len(cases)}): finite, nothing lost or escaped, overlap within tolerance",
                 f"{sum(r[3] for r in rows):.0f} s in all",
                 f"{sum('passes' in r[-1] for r in rows)} pass, {len(known)} known failures"
                 + (f"; UNEXPECTED: {', '.join(failures)}" if failures else "")),
        Table(f"Hard cases at the pinned settings unless stated; sampled every {SAMPLE:g} s (head-on: 2 ms); overlaps (dots and walls) "
              "in % of r, with their tolerance",
              ["case", "dots", "steps", "wall (s)", "ms/step", "worst overlap, any sample", "settled overlap",
               "finite", "lost / escaped / crossed", "engine warned: too fast", "verdict"], rows),
        Note("Known failures (measured; the tests expect them, strict xfail):\n\n"
             + "\n".join(f"- **{c.name}**: {c.known_failure}." for c in known) if known
             else "Known failures are slow cases: run without --quick."),
    ]


def main(argv: list[str] | None = None) -> int:
    return cli(run, __doc__.splitlines()[0], argv)


if __name__ == "__main__":
    raise SystemExit(main())
