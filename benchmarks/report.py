"""What a benchmark returns, and the report made of it.

A benchmark module exposes ``run(quick: bool) -> list[Result]``; a result is a
`Table` (every row: time AND error measured in the same run), a `Figure`, a
`Note` or a `Headline` (one line of the report's summary table). The harness
(``python -m benchmarks``) turns them into ``docs/performance.md`` and
``docs/figures/*.png``; a module's own ``python -m benchmarks.<name>`` prints
them (`print_results`) and saves its figures on request (`cli`).
"""

from __future__ import annotations

import argparse
import datetime
import io
import json
import math
import os
import platform
import subprocess
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from matplotlib.figure import Figure as MplFigure

from labrig.files import atomic_path


@dataclass
class Table:
    """A markdown table; cells are text or numbers (`cell` formats numbers)."""

    title: str
    columns: Sequence[str]
    rows: list[Sequence] = field(default_factory=list)
    note: str = ""

    def markdown(self) -> str:
        align = ["---:" if _numeric_column(self.rows, k) else "---" for k in range(len(self.columns))]
        lines = [f"**{self.title}**", "", "| " + " | ".join(_escape(c) for c in self.columns) + " |",
                 "|" + "|".join(align) + "|"]
        lines += ["| " + " | ".join(_escape(cell(v)) for v in row) + " |" for row in self.rows]
        if self.note:
            lines += ["", self.note]
        return "\n".join(lines)


@dataclass
class Figure:
    """A matplotlib figure saved as ``figures/<name>.png``."""

    name: str
    figure: MplFigure
    caption: str


@dataclass
class Note:
    """A paragraph of text (markdown)."""

    text: str


@dataclass
class Headline:
    """One row of the report's summary: what was measured, its time and its error."""

    what: str
    time: str
    error: str


Result = Table | Figure | Note | Headline


def cell(value: object) -> str:
    """A table cell: ints with thousands separators, floats to 3 significant digits."""
    if isinstance(value, bool) or value is None:
        return "" if value is None else str(value)
    if isinstance(value, int):
        return f"{value:,}"
    if isinstance(value, float):
        if math.isnan(value) or math.isinf(value):
            return str(value)
        if value == 0:
            return "0"
        if 1e-3 <= abs(value) < 1e5:
            return f"{value:.3g}"
        return f"{value:.2e}"
    return str(value)


def _escape(text: str) -> str:
    return text.replace("|", "\\|")


def _numeric_column(rows: list[Sequence], k: int) -> bool:
    """Right-align a column whose every cell starts like a number."""
    return bool(rows) and all(cell(row[k])[:1] in set("0123456789+-.") and cell(row[k]) for row in rows)


def machine_info() -> dict[str, str]:
    """CPU model, cores, load, versions of the numerical stack, date and git commit."""
    import matplotlib
    import numpy
    import pymunk
    import scipy

    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                                cwd=Path(__file__).parent, timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        commit = ""
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    return {
        "cpu": f"{cpu}, {os.cpu_count()} cores ({platform.machine()})",
        "load": f"{load:.2f}",
        "python": platform.python_version(),
        "numpy": numpy.__version__,
        "scipy": scipy.__version__,
        "pymunk": f"{pymunk.version} (Chipmunk {pymunk.chipmunk_version.split('-')[0]})",
        "matplotlib": matplotlib.__version__,
        "date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
        "commit": commit or "unknown",
    }


def machine_line(info: dict[str, str]) -> str:
    return (f"{info['cpu']}; Python {info['python']}, numpy {info['numpy']}, scipy {info['scipy']}, "
            f"pymunk {info['pymunk']}; 1-min load {info['load']} at start; {info['date']}, commit {info['commit']}")


def section_markdown(results: Sequence[Result], figure_dir: str = "figures") -> str:
    """The markdown of one benchmark's results (headlines excluded), figures linked under ``figure_dir``."""
    parts = []
    for result in results:
        if isinstance(result, Table):
            parts.append(result.markdown())
        elif isinstance(result, Note):
            parts.append(result.text)
        elif isinstance(result, Figure):
            parts.append(f"![{result.name}]({figure_dir}/{result.name}.png)\n\n*{result.caption}*")
    return "\n\n".join(parts)


def load_store(path: Path, table: str, what: str = "report") -> dict:
    """The stored data of a generated report (``{"machine": {}, table: {}}`` when there is none yet).

    Raises ValueError (naming the file and how to start afresh) when it cannot be read or has no
    ``table``; the file is never changed here.
    """
    if not path.exists():
        return {"machine": {}, table: {}}
    try:
        store = json.loads(path.read_text())
        if not isinstance(store, dict) or not isinstance(store.get(table), dict):
            raise ValueError(f"no {table!r} table")
        return store
    except (OSError, ValueError) as exc:
        raise ValueError(f"cannot read the previous {what} data {path}: {exc} (move it away to start afresh)") \
            from None


def save_figure(figure: MplFigure, path: Path) -> Path:
    """Write ``figure`` as a PNG at ``path``, atomically."""
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=110, bbox_inches="tight")
    with atomic_path(path) as tmp:
        tmp.write_bytes(buffer.getvalue())
    return path


def print_results(results: Sequence[Result], file=None) -> None:
    """Print tables, notes and headlines as markdown (figures by caption only)."""
    file = file or sys.stdout
    for result in results:
        if isinstance(result, Headline):
            print(f"headline: {result.what}: {result.time}; error {result.error}", file=file)
        elif isinstance(result, Figure):
            print(f"[figure {result.name}: {result.caption}]", file=file)
        else:
            print(section_markdown([result]), file=file)
        print(file=file)


def cli_with_options(parser: argparse.ArgumentParser, make_results: Callable[[argparse.Namespace], list[Result]],
                     argv: list[str] | None = None) -> int:
    """A benchmark module's ``main`` with options of its own: parse ``argv`` with ``parser``, print the Python
    and numpy versions and the results of ``make_results(args)``."""
    import numpy

    args = parser.parse_args(argv)
    print(f"python {platform.python_version()}, numpy {numpy.__version__}, {platform.machine()}\n")
    print_results(make_results(args))
    return 0


def cli(run: Callable[[bool], list[Result]], description: str, argv: list[str] | None = None) -> int:
    """A benchmark module's ``main``: ``[--quick] [--figures DIR]``, print the results."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--quick", action="store_true", help="the small version run by the test suite")
    parser.add_argument("--figures", type=Path, default=None, help="also save the figures (PNG) in this directory")
    args = parser.parse_args(argv)
    print(machine_line(machine_info()) + "\n")
    results = run(args.quick)
    print_results(results)
    if args.figures is not None:
        args.figures.mkdir(parents=True, exist_ok=True)
        for result in results:
            if isinstance(result, Figure):
                print(f"wrote {save_figure(result.figure, args.figures / f'{result.name}.png')}")
    return 0
