"""What the ``qdots`` subcommands do; `qdots.cli.main` parses arguments and calls these.

Every command that runs dots writes, per experiment, into its output directory:
``<slug>.npz`` (final checkpoint, resumable), ``<slug>.png``, optionally
``<slug>.mp4`` and ``<slug>.gsd``, the experiment file ``<slug>.toml`` for
provenance, and one ``summary.csv`` row. A run's files are one `labrig.files.OutputSet`:
written when the run has finished, all together (the experiment file last), so a run that
fails or is killed leaves the earlier files of the same name as they were. The experiment file
a run was started from is never written over (its provenance copy is then ``<slug>.ran.toml``).
A board the engine produced is always saved; its worst overlap and the dots that left an open
board are measured, printed as a warning when large, and recorded in the summary.
"""

from __future__ import annotations

import csv
import sys
import time
from pathlib import Path
from typing import Sequence

from labrig.cli import print_table
from labrig.files import OutputSet, slug, write_csv

from ..analysis.packing import packing_summary
from ..io import checkpoint
from ..simulation import OVERLAP_WARNING, Simulation

#: Simulated time between movie frames, s.
FRAME_INTERVAL = 0.5


def _recorders(files: OutputSet, sim: Simulation, stem: str, movie: bool, gsd: bool) -> None:
    """Attach the requested movie and trajectory writers to ``sim``, as streams of the output set."""
    every = max(1, round(FRAME_INTERVAL / sim.dt))
    if movie:
        from ..render import MovieWriter

        sim.attach(files.adopt(MovieWriter(files.target(f"{stem}.mp4"), every=every)))
    if gsd:
        from ..io.trajectory import GSDWriter

        sim.attach(files.adopt(GSDWriter(files.target(f"{stem}.gsd"), every=every, dt=sim.dt)))


def finish(sim: Simulation, files: OutputSet, stem: str, wall: float, extra: dict) -> dict:
    """Stage the checkpoint and picture of a finished run; return its summary row (and warn when the
    board overlaps a lot or dots left it)."""
    from ..render import save_png

    state = sim.state()
    save_png(state, files.stage(f"{stem}.png"))
    summary = packing_summary(state)
    checkpoint.save(sim, files.stage(f"{stem}.npz"))
    if summary["max_overlap"] > OVERLAP_WARNING:
        print(f"warning: {stem}: dots overlap by up to {100 * summary['max_overlap']:.1f} % of a radius (more than "
              f"{100 * OVERLAP_WARNING:g} %): the time step is too large for these speeds", file=sys.stderr)
    if summary["escaped_dots"]:
        print(f"warning: {stem}: {summary['escaped_dots']} of {summary['n_dots']} dots have left the open board",
              file=sys.stderr)
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
        "escaped_dots": summary["escaped_dots"],
        "kinetic_energy": summary["kinetic_energy"],
        "state_file": f"{stem}.npz",
    }


def merge_summary(path: Path, rows: Sequence[dict]) -> Path:
    """Add ``rows`` to the CSV at ``path``, replacing earlier rows of the same ``state_file``.

    Earlier rows of other runs are kept (a resume never loses a preset's
    table), a replaced row keeps the fields the new one does not set, and the
    columns are the union, in order of first appearance. An unreadable earlier
    table is set aside as ``summary.csv.unreadable`` (with a warning), not lost.
    """
    old = []
    if path.exists():
        try:
            with open(path, newline="", encoding="utf-8") as stream:
                old = [row for row in csv.DictReader(stream) if None not in row and None not in row.values()]
        except (OSError, UnicodeDecodeError, csv.Error) as exc:
            kept = path.with_name(path.name + ".unreadable")
            path.replace(kept)
            print(f"warning: {path} could not be read ({exc}); kept as {kept}, starting a new table", file=sys.stderr)
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
            ("dots", str(row["dots"]) + (f" ({row['escaped_dots']} left the board)" if row["escaped_dots"] else "")),
            ("simulated time", f"{row['time_s']:.2f} s ({row['steps']} steps)"),
            ("wall time", f"{row['wall_s']:.1f} s ({row['x_real_time']:.1f}x real time)"),
            ("interior fraction", f"{row['interior_fraction']:.3f}"),
            ("mean neighbours (interior)", f"{row['mean_neighbours_interior']:.2f}"),
            ("max overlap", f"{100 * row['max_overlap']:.3f} % of radius"),
        ])
    print(f"wrote {out / 'summary.csv'} and the .npz/.png files beside it")


def run_experiments(experiments: Sequence, out: Path, *, movie: bool, gsd: bool, progress: bool = True,
                    source: Path | None = None) -> list[dict]:
    """Run each experiment, writing its files into ``out``; returns the summary rows.

    ``source`` is the experiment file they were read from: it is never written over.
    """
    from ..experiment import build_simulation, populate
    from ..io.experiment_file import save_experiment

    rows = []
    for exp in experiments:
        stem = slug(exp.name)
        start = time.perf_counter()
        with OutputSet(out) as files:
            sim = build_simulation(exp)
            _recorders(files, sim, stem, movie, gsd)
            populate(sim, exp, progress=progress)
            rows.append(finish(sim, files, stem, time.perf_counter() - start,
                               {"name": exp.name, "seed": exp.seed, "sigma": exp.deposition.sigma,
                                "mass_model": exp.deposition.mass_model, "grating_px": exp.grating}))
            save_experiment(exp, files.stage(files.name_beside(f"{stem}.toml", source), last=True))
    report(rows, out)
    return rows


def resume(state_path: Path, seconds: float, out: Path | None, *, movie: bool, gsd: bool) -> dict:
    """Continue a saved run for ``seconds``; the new checkpoint replaces the old one unless ``out`` is given.

    The old checkpoint is replaced only once the continuation has finished and its files are written.
    """
    sim = checkpoint.load(state_path)
    out = state_path.parent if out is None else out
    stem = state_path.stem
    start = time.perf_counter()
    with OutputSet(out) as files:
        _recorders(files, sim, stem, movie, gsd)
        sim.run(seconds, progress=True)
        row = finish(sim, files, stem, time.perf_counter() - start, {"resumed_from": str(state_path)})
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
            forster_radii: float | None = None, trap_fraction: float = 1.0 / 3.0, draws: int = 8, seed: int = 0,
            as_json: bool = False, plot: Path | None = None) -> dict:
    """Print the packing table and the film LQE of a saved board; optionally write the figure.

    Returns the summary (the ``--json`` object).
    """
    import json
    import math

    from ..analysis.report import board_report, save_report_png, table_rows

    state = checkpoint.read_state(state_path)
    report = board_report(state, rule=rule, forster_radius=forster_radius, forster_radii=forster_radii,
                          trap_fraction=trap_fraction, draws=draws, seed=seed)
    summary = {"state_file": str(state_path), "rule": rule, **report.summary}
    if plot is not None:
        summary["figure"] = str(save_report_png(state, report, plot))
    if as_json:  # strict JSON: nan and inf -> null
        print(json.dumps({k: None if isinstance(v, float) and not math.isfinite(v) else v for k, v in summary.items()},
                         indent=2))
    else:
        print_table(f"{state_path} (t = {state.time:.2f} s, neighbour rule {rule!r}):", table_rows(summary))
        if plot is not None:
            print(f"wrote {plot}")
    return summary
