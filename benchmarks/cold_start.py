"""Cold start: how fast the command lines answer, and the first run after installing against later runs.

The command lines' start: ``qdots --help``, ``--version`` and argument errors (and ``planarize``'s), each run
`START_REPEATS` times in a fresh process as the console command runs it; the fewest seconds of each are
reported (the machine may be shared: the fewest is the command's own cost), beside Python's own start.

The first run: each command of `COMMANDS` runs twice in a fresh process with its own empty numba cache
directory (``NUMBA_CACHE_DIR``): first cold, as on a fresh install, then warm, loading what the first run cached.
``compile`` is the cold wall time less the warm one. The commands run as a user types them, their sizes given
(the demo's dots, seconds, spread and seed): the engine settings they run are the commands' own defaults, which
is what a first run after installing meets. ``error`` compares the two runs' results (the summary
table's numbers): compiling or loading a kernel must not change what it computes, so 0 is expected.

Run: ``python -m benchmarks.cold_start [--quick] [--start-only]``
"""

from __future__ import annotations

import argparse
import csv
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from .report import Headline, Note, Table, print_results

#: The code this benchmark measures (besides itself): a commit to it after a run marks the run's section as
#: older than its code (`benchmarks.staleness`).
MEASURED_CODE = ("qdots", "planarize", "labrig")

#: The commands timed: name -> (arguments of ``python -m``, the name pattern of a table it writes into its --out).
COMMANDS = {
    "qdots demo": (["qdots", "demo", "--no-movie", "--seed", "1", "--dots", "150", "--seconds", "20", "--sigma",
                    "0.05"], "*/summary.csv"),  # (each run in its own folder)
    "planarize scene hill": (["planarize", "scene", "hill"], "*/*_history.csv"),  # (each run in its own folder)
}
#: Longest a command may take, s.
TIMEOUT = 1800
#: The command-line answers timed: (program, arguments); the first ones must load no simulator.
STARTS = [
    ("python", []),  # Python's own start, for scale
    ("qdots", ["--help"]), ("qdots", ["--version"]), ("qdots", ["nosuch"]), ("qdots", ["run"]),
    ("qdots", ["run", "x.toml", "--engine", "verlet"]), ("qdots", ["preset", "nosuch"]), ("qdots", ["analyze"]),
    ("planarize", ["--help"]), ("planarize", ["--version"]), ("planarize", ["nosuch"]),
    ("qdots", ["measure"]), ("planarize", ["run"]),
    ("qdots", ["measure", "--help"]), ("qdots", ["compare", "--help"]), ("qdots", ["infer", "--help"]),
    ("planarize", ["import", "--help"]), ("qdots", ["measure", "nofile.png"]),  # bounds from light modules
]
#: How often each answer is timed (`--quick`: fewer).
START_REPEATS = 9
#: How the console commands start (setuptools' entry-point script, ``labrig.launch``).
CONSOLE = "import sys; from labrig.launch import {prog}; sys.exit({prog}())"


def start_seconds(prog: str, argv: list[str], repeats: int) -> list[float]:
    """Wall seconds of ``repeats`` fresh processes answering ``prog argv`` as the console command does."""
    code = "pass" if prog == "python" else CONSOLE.format(prog=prog)
    out = []
    for _ in range(repeats):
        start = time.perf_counter()
        subprocess.run([sys.executable, "-c", code, *argv], capture_output=True, timeout=TIMEOUT)
        out.append(time.perf_counter() - start)
    return out


def starts(repeats: int) -> list:
    """The table of the command lines' start, and its headline."""
    rows = []
    for prog, argv in STARTS:
        seconds = sorted(start_seconds(prog, argv, repeats))
        rows.append([" ".join([prog, *argv]) if prog != "python" else "python -c pass", seconds[0],
                     seconds[len(seconds) // 2]])
    worst = max(row[1] for row in rows[1:-2])
    return [Table(f"Command-line start (s, whole process, {repeats} runs each)", ["command", "fewest", "median"], rows,
                  note="As the console commands run (``labrig.launch``); the fewest is the command's own cost on a "
                       "machine others share. The last two build parsers whose bounds live in the simulators' modules "
                       "(the micrograph reader's, planarize's engines)."),
            Headline("command-line start: --help, --version and argument errors", f"{worst:.2f} s at most (fewest "
                     f"of {repeats})", "n/a")]


def timed_run(argv: list[str], out: Path, cache: Path) -> float:
    """Wall seconds of ``python -m ARGV --out OUT`` with numba's cache in ``cache``."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache)}
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", *argv, "--out", str(out)], env=env, check=True, capture_output=True,
                   timeout=TIMEOUT)
    return time.perf_counter() - start


def numbers(directory: Path, pattern: str) -> dict[tuple[int, str], float]:
    """The numeric cells of the one table matching ``pattern`` in ``directory``, by (row, column); timing columns
    left out."""
    (table,) = directory.glob(pattern)
    with open(table, newline="", encoding="utf-8") as stream:
        rows = list(csv.DictReader(stream))
    out = {}
    for k, row in enumerate(rows):
        for key, text in row.items():
            if "wall" in key or "per_s" in key or "real_time" in key:
                continue
            try:
                out[k, key] = float(text)
            except (TypeError, ValueError):
                continue
    return out


def difference(a: dict, b: dict) -> float:
    """Largest |a - b| over the cells both have (nan equal to nan); inf when they hold different cells."""
    if a.keys() != b.keys():
        return math.inf
    worst = 0.0
    for key in a.keys() & b.keys():
        x, y = a[key], b[key]
        if not (math.isnan(x) and math.isnan(y)):
            worst = max(worst, abs(x - y))
    return worst


def run(quick: bool, start_only: bool = False) -> list:
    results = starts(3 if quick else START_REPEATS)
    if start_only:
        return results
    rows, headlines = [], []
    for argv, table in COMMANDS.values():
        argv = argv + (["--seconds", "2"] if quick and argv[0] == "qdots" else [])
        argv = argv + (["--quick", "0.25"] if quick and argv[0] == "planarize" else [])
        with tempfile.TemporaryDirectory() as tmp:
            tmp = Path(tmp)
            cold = timed_run(argv, tmp / "cold", tmp / "cache")
            warm = timed_run(argv, tmp / "warm", tmp / "cache")
            error = difference(numbers(tmp / "cold", table), numbers(tmp / "warm", table))
        rows.append([" ".join(argv), cold, warm, cold - warm, error])
        headlines.append(Headline(f"cold start: `{' '.join(argv)}`", f"{cold:.1f} s first run, {warm:.1f} s later",
                                  f"{error:.3g} (cold vs warm results)"))
    return [Table("Cold and warm runs (s, whole process)", ["command", "cold", "warm", "compile", "error"], rows,
                  note="cold: a fresh numba cache, as after installing; warm: the same command again. The bars "
                       "say when they compile and leave it out of their ETA."),
            Note("The first run of each command compiles its kernels once per machine (and again after an "
                 "upgrade of numba or of the package); every later run loads them."), *headlines, *results]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="shorter runs")
    parser.add_argument("--start-only", action="store_true", help="only the command lines' start")
    args = parser.parse_args(argv)
    print_results(run(args.quick, args.start_only))
    return 0


if __name__ == "__main__":
    sys.exit(main())
