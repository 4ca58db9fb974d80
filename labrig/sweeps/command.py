"""The ``sweep`` and ``sweep-plot`` subcommands, shared by the ``qdots`` and ``planarize`` command lines.

`sweep_command` and `plot_command` make their `labrig.cli.Command` entries; the sweep machinery is imported only
when one of them is chosen.
"""

from __future__ import annotations

import argparse
import functools
import sys
from pathlib import Path
from typing import Callable

from ..cli import Command, fraction, int_in, print_table
from ..files import slug
from ..launch import LateInterrupt
from ..validate import InputError, printable


def sweep_command(package: str, what: str, load: Callable[[Path], object], make_runner: Callable,
                  quick_help: str) -> Command:
    """``<package> sweep SWEEP.toml [--out DIR] [--workers N] [--scheduler ADDRESS] [--quick F]``.

    ``load(path)`` reads the package's sweep files (a `labrig.sweeps.files.SweepFile`); ``make_runner(quick)``
    makes its runner. Both are called only when the command runs.
    """
    description = (f"Run every run of a sweep file (a base plus axes, points and seeds) of {what}. Each run "
                   "writes one record under DIR/runs/ as soon as it ends; running the sweep again skips "
                   "finished runs. The table of all runs goes to DIR/table.csv (and table.parquet with "
                   f"pyarrow). Exit status 1 if some run failed (its error is in the table). "
                   f"Plot it with '{package} sweep-plot'.")
    return Command("sweep", f"run a parameter sweep of {what} (local cores or a Dask cluster)",
                   functools.partial(_run_command, load=load, make_runner=make_runner),
                   functools.partial(_sweep_arguments, quick_help=quick_help), description)


def _sweep_arguments(p: argparse.ArgumentParser, quick_help: str) -> None:
    from .backends import MAX_WORKERS
    from .execute import MAX_RETRIES
    from .spec import DEFAULT_MAX_RUNS, MAX_RUNS

    p.add_argument("sweep", type=Path, metavar="SWEEP.toml", help="sweep file; the paths in it (base, output.dir) "
                   "are relative to the sweep file's folder")
    p.add_argument("--out", type=Path, default=None, metavar="DIR",
                   help="output directory (default: the file's output.dir, relative to the sweep file, else the "
                        "file's name beside it); printed, resolved, when the sweep starts")
    p.add_argument("--max-runs", type=int_in(1, MAX_RUNS), default=DEFAULT_MAX_RUNS, metavar="N",
                   help=f"refuse a sweep of more runs than this (default {DEFAULT_MAX_RUNS:,}, at most {MAX_RUNS:,}); "
                        "the run count is printed before anything runs")
    p.add_argument("--workers", type=int_in(1, MAX_WORKERS), default=None, metavar="N",
                   help="local worker processes (default: all cores; 1 runs in this process)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run on this Dask scheduler (e.g. tcp://10.0.0.5:8786; needs nanodisorder[sweep])")
    p.add_argument("--retries", type=int_in(0, MAX_RETRIES), default=1, metavar="K",
                   help="extra attempts for a run that fails (default 1)")
    p.add_argument("--quick", type=fraction, default=None, metavar="F", help=quick_help)


def _run_command(args: argparse.Namespace, load, make_runner) -> int:
    return run_sweep_command(args, load(args.sweep), make_runner(args.quick))


def run_sweep_command(args: argparse.Namespace, sweep_file, runner) -> int:
    """Run a parsed sweep file (`labrig.sweeps.files.SweepFile`) with the command's options; print what happened."""
    from .execute import run_sweep

    out = sweep_file.out if args.out is None else args.out
    result = run_sweep(sweep_file.sweep, runner, out, workers=args.workers, scheduler=args.scheduler,
                       retries=args.retries, state=sweep_file.state, max_runs=args.max_runs)
    try:
        return _report(result, sweep_file, out)
    except KeyboardInterrupt:  # every result is on disk by now: say so
        raise LateInterrupt(f"every run's result was written ({result.table})") from None


def _report(result, sweep_file, out) -> int:
    """Print what a finished sweep did; its exit status (1 if some run failed)."""
    rows = [("runs", str(len(result.rows))), ("ran now", str(result.ran)),
            ("already done", str(result.skipped)), ("failed", str(result.failed)), ("table", str(result.table))]
    if result.parquet is not None:
        rows.append(("parquet", str(result.parquet)))
    print_table(f"{sweep_file.source}:", rows)
    failed = [row for row in result.rows if row["status"] != "ok"]
    for row in failed[:5]:
        print(f"run {row['run']} failed: {printable(str(row['error']))} (details: {Path(out) / 'runs' / row['run']}.json)",
              file=sys.stderr)
    if len(failed) > 5:
        print(f"... and {len(failed) - 5} more failed runs (see the table's error column)", file=sys.stderr)
    return 1 if failed else 0


def _assignment(text: str) -> tuple[str, str]:
    column, sep, value = text.partition("=")
    if not sep or not column:
        raise argparse.ArgumentTypeError(f"must be COLUMN=VALUE, got {text!r}")
    return column, value


def plot_command(package: str) -> Command:
    """``<package> sweep-plot TABLE --metric M --x AXIS [--group AXIS] [--where COLUMN=VALUE] ...``."""
    return Command("sweep-plot", "plot mean +- standard error of a sweep metric against an axis", run_plot_command,
                   _plot_arguments,
                   f"Average a metric of a table written by '{package} sweep' over the runs that share the x "
                   "value (and the group value): mean +- standard error over seeds, one curve per group. "
                   "Prints the numbers and writes a PNG.")


def _plot_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("table", type=Path, metavar="TABLE", help="table.csv or table.parquet of a sweep")
    p.add_argument("--metric", required=True, metavar="M", help="column to average, e.g. interior_fraction")
    p.add_argument("--x", required=True, metavar="AXIS", help="column on the x axis, e.g. deposition.sigma")
    p.add_argument("--group", default=None, metavar="AXIS", help="one curve per value of this column")
    p.add_argument("--where", type=_assignment, action="append", default=[], metavar="COLUMN=VALUE",
                   help="keep only these rows (repeatable)")
    p.add_argument("--title", default=None, help="figure title")
    p.add_argument("--out", type=Path, default=None, metavar="FILE.png",
                   help="default: METRIC_vs_X[_by_GROUP].png beside the table")


def run_plot_command(args: argparse.Namespace) -> int:
    """Plot a sweep's table (the ``sweep-plot`` subcommand)."""
    from .plot import save_sweep_plot, summarize, summary_lines

    if args.out is not None and args.out.suffix.lower() != ".png":
        raise InputError(f"--out must name a .png file (the plot is a PNG), got {str(args.out)!r}")
    where = dict(args.where)
    summary = summarize(args.table, args.metric, args.x, args.group, where)
    name = f"{args.metric}_vs_{args.x}" + (f"_by_{args.group}" if args.group else "")
    png = args.table.parent / f"{slug(name)}.png" if args.out is None else args.out
    save_sweep_plot(png, args.table, args.metric, args.x, args.group, where, title=args.title)
    print("\n".join(summary_lines(summary, args.metric, args.x, args.group)))
    print(f"wrote {png}")
    return 0
