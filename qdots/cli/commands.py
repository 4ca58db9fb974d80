"""What the ``qdots`` subcommands do; `qdots.cli` parses arguments and calls these.

Every command that runs dots writes, per experiment, into its output directory:
``<slug>.npz`` (final checkpoint, resumable), ``<slug>.png``, optionally
``<slug>.mp4`` and ``<slug>.gsd``, the scene file ``<slug>.toml`` for
provenance, and one ``summary.csv`` row; all files atomically.
"""

from __future__ import annotations

import csv
import time
from contextlib import ExitStack
from pathlib import Path
from typing import Sequence

from labrig.cli import print_table
from labrig.files import slug, write_csv

from ..analysis.packing import packing_summary
from ..io import checkpoint
from ..simulation import Simulation

#: Simulated time between movie frames, s.
FRAME_INTERVAL = 0.5


def _recorders(stack: ExitStack, out: Path, stem: str, dt: float, movie: bool, gsd: bool) -> list:
    every = max(1, round(FRAME_INTERVAL / dt))
    writers = []
    if movie:
        from ..render import MovieWriter

        writers.append(stack.enter_context(MovieWriter(out / f"{stem}.mp4", every=every)))
    if gsd:
        from ..io.trajectory import GSDWriter

        writers.append(stack.enter_context(GSDWriter(out / f"{stem}.gsd", every=every, dt=dt)))
    return writers


def finish(sim: Simulation, out: Path, stem: str, wall: float, extra: dict) -> dict:
    """Save checkpoint and picture of a finished run; return its summary row."""
    from ..render import save_png

    state = sim.state()
    save_png(state, out / f"{stem}.png")
    summary = packing_summary(state)
    checkpoint.save(sim, out / f"{stem}.npz")
    return {
        **extra,
        "dots": summary["n_dots"],
        "time_s": round(state.time, 9),
        "steps": sim.steps_taken,
        "wall_s": round(wall, 3),
        "x_real_time": round(sim.steps_taken * sim.dt / wall, 3) if wall > 0 else float("nan"),
        "interior_fraction": summary["interior_fraction"],
        "mean_neighbours_interior": summary["mean_neighbours_interior"],
        "max_overlap": summary["max_overlap"],
        "kinetic_energy": summary["kinetic_energy"],
        "state_file": f"{stem}.npz",
    }


def merge_summary(path: Path, rows: Sequence[dict]) -> Path:
    """Add ``rows`` to the CSV at ``path``, replacing earlier rows of the same ``state_file``.

    Earlier rows of other runs are kept (a resume never loses a preset's
    table), a replaced row keeps the fields the new one does not set, and the
    columns are the union, in order of first appearance.
    """
    old = []
    if path.exists():
        with open(path, newline="") as stream:
            old = list(csv.DictReader(stream))
    previous = {row.get("state_file"): row for row in old}
    fresh = {row["state_file"] for row in rows}
    # a resumed run keeps the parameters its earlier row recorded
    merged = [row for row in old if row.get("state_file") not in fresh] + [
        {**previous.get(row["state_file"], {}), **row} for row in rows]
    columns = list(dict.fromkeys(key for row in merged for key in row))
    return write_csv(path, [{key: row.get(key, "") for key in columns} for row in merged])


def report(rows: Sequence[dict], out: Path) -> None:
    merge_summary(out / "summary.csv", rows)
    for row in rows:
        print_table(f"{row.get('name', row['state_file'])}:", [
            ("dots", str(row["dots"])),
            ("simulated time", f"{row['time_s']:.2f} s ({row['steps']} steps)"),
            ("wall time", f"{row['wall_s']:.1f} s ({row['x_real_time']:.1f}x real time)"),
            ("interior fraction", f"{row['interior_fraction']:.3f}"),
            ("mean neighbours (interior)", f"{row['mean_neighbours_interior']:.2f}"),
            ("max overlap", f"{100 * row['max_overlap']:.3f} % of radius"),
        ])
    print(f"wrote {out / 'summary.csv'} and the .npz/.png files beside it")


def run_experiments(experiments: Sequence, out: Path, *, movie: bool, gsd: bool, progress: bool = True) -> list[dict]:
    """Run each experiment, writing its files into ``out``; returns the summary rows."""
    from ..experiment import run_experiment
    from ..io.experiment_file import save_experiment

    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for exp in experiments:
        stem = slug(exp.name)
        save_experiment(exp, out / f"{stem}.toml")
        start = time.perf_counter()
        with ExitStack() as stack:
            writers = _recorders(stack, out, stem, exp.engine.dt, movie, gsd)
            sim = run_experiment(exp, progress=progress, writers=writers)
        rows.append(finish(sim, out, stem, time.perf_counter() - start,
                           {"name": exp.name, "seed": exp.seed, "sigma": exp.deposition.sigma,
                            "mass_model": exp.deposition.mass_model, "grating_px": exp.grating}))
    report(rows, out)
    return rows


def resume(state_path: Path, seconds: float, out: Path | None, *, movie: bool, gsd: bool) -> dict:
    """Continue a saved run for ``seconds``; the new checkpoint replaces the old one unless ``out`` is given."""
    sim = checkpoint.load(state_path)
    out = state_path.parent if out is None else out
    out.mkdir(parents=True, exist_ok=True)
    stem = state_path.stem
    start = time.perf_counter()
    with ExitStack() as stack:
        writers = _recorders(stack, out, stem, sim.dt, movie, gsd)
        sim.run(seconds, progress=True, writers=writers)
    row = finish(sim, out, stem, time.perf_counter() - start, {"resumed_from": str(state_path)})
    report([row], out)
    return row


def render(state_path: Path, png: Path | None) -> Path:
    """Picture of a saved board."""
    from ..render import save_png

    png = state_path.with_suffix(".png") if png is None else png
    save_png(checkpoint.read_state(state_path), png)
    print(f"wrote {png}")
    return png


def analyze(state_path: Path, *, rule: str = "text", forster_radius: float | None = None,
            trap_fraction: float = 1.0 / 3.0, draws: int = 8, seed: int = 0, as_json: bool = False,
            plot: Path | None = None) -> dict:
    """Print the packing table and the film LQE of a saved board; optionally write the figure.

    Returns the summary (the ``--json`` object).
    """
    import json
    import math

    from ..analysis.report import board_report, save_report_png, table_rows

    state = checkpoint.read_state(state_path)
    report = board_report(state, rule=rule, forster_radius=forster_radius, trap_fraction=trap_fraction,
                          draws=draws, seed=seed)
    summary = {"state_file": str(state_path), "rule": rule, **report.summary}
    if plot is not None:
        summary["figure"] = str(save_report_png(state, report, plot))
    if as_json:  # strict JSON: nan -> null
        print(json.dumps({k: None if isinstance(v, float) and math.isnan(v) else v for k, v in summary.items()},
                         indent=2))
    else:
        print_table(f"{state_path} (t = {state.time:.2f} s, neighbour rule {rule!r}):", table_rows(summary))
        if plot is not None:
            print(f"wrote {plot}")
    return summary
