"""What the ``qdots`` subcommands do; `qdots.cli.main` parses arguments and calls these.

Every command that runs dots writes, per experiment, into its output directory:
``<slug>.npz`` (final checkpoint, resumable), ``<slug>.png``, optionally
``<slug>.mp4`` and ``<slug>.gsd``, the experiment file ``<slug>.toml`` for
provenance, and one ``summary.csv`` row. A run's files, its summary row included, are one
`labrig.files.OutputSet`: locked when the run starts (a second run of the same name into the same
directory is refused), written when the run has finished, all at once (a kill mid-switch is
finished by the next command that opens the directory), so a run that fails or is killed leaves the
earlier files of the same name as they were. The experiment file a run was started from is never
written over (its provenance copy is then ``<slug>.ran.toml``). A board the engine produced is always
saved; its worst overlap and the dots that left an open board are measured, printed as a warning when
large, and recorded in the summary.

Which earlier files a run replaces (`RESUME_RULE` for a resume): a new run replaces the whole set of
its name, summary row included; an earlier ``<slug>.mp4`` or ``<slug>.gsd`` that it does not rewrite,
and the ``<slug>.until-Ts.mp4`` / ``.gsd`` that resumes kept, are removed with the rest (they showed the
run whose state is gone), and the command says so.
"""

from __future__ import annotations

import csv
import os
import re
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
#: The summary's column of the worst overlap: percent of the pair's mean radius (what the terminal prints).
OVERLAP_COLUMN = "max_overlap_pct_radius"
#: The files a run records on request: suffix, what it is, its option.
RECORDINGS = ((".mp4", "movie", "--movie"), (".gsd", "trajectory", "--gsd"))
#: What `qdots resume` writes, in its --help and the README.
RESUME_RULE = (
    "Resuming in place (no --out, or --out the state's own directory) replaces the run's set as one unit, "
    "all at once when the continuation has finished: STATE.npz, STATE.png, its summary.csv row, and "
    "STATE.mp4 / STATE.gsd when --movie / --gsd are given. An earlier STATE.mp4 or STATE.gsd is never lost: "
    "the same switch keeps it as STATE.until-Ts.mp4 (.gsd), T the time in s of the state resumed from (it "
    "shows the run up to T s); a new STATE.mp4 shows the continuation only. A line is printed for each file "
    "kept. Resuming into another directory writes the set of that name there as a run does (an earlier "
    "movie or trajectory of that name there is removed). A set that another run is writing is refused.")


def _recorders(files: OutputSet, sim: Simulation, stem: str, movie: bool, gsd: bool,
               earlier_until: float | None = None) -> None:
    """Attach the requested movie and trajectory writers to ``sim``, as streams of the output set, and say what
    becomes of the set's earlier ones: kept as ``stem.until-Ts.SUFFIX`` when ``earlier_until`` (T, s) is
    given (a resume in place), else removed unless rewritten."""
    every = max(1, round(FRAME_INTERVAL / sim.dt))
    if movie:
        from ..render import MovieWriter

        sim.attach(files.adopt(MovieWriter(files.stage(f"{stem}.mp4"), every=every)))
    if gsd:
        from ..io.trajectory import GSDWriter

        sim.attach(files.adopt(GSDWriter(files.stage(f"{stem}.gsd"), every=every, dt=sim.dt)))
    for suffix, _, _ in RECORDINGS:
        if earlier_until is None:
            files.drop(f"{stem}{suffix}")
        else:
            files.keep_as(f"{stem}{suffix}", f"{stem}.until-{seconds_label(earlier_until)}s{suffix}")
    if earlier_until is None:  # the earlier parts of the replaced run's movies (not a set of such a name)
        for name in sorted(os.listdir(files.directory)):
            part = re.fullmatch(re.escape(stem) + r"(\.until-[0-9.]+s(?:-[0-9]+)?)\.(mp4|gsd)", name)
            if part and not files.target(f"{stem}{part[1]}.npz").exists():
                files.drop(name)


def seconds_label(seconds: float) -> str:
    """A time for a file name, s: ``20.0`` -> ``"20"``, ``0.1300000001`` -> ``"0.13"`` (to the ms)."""
    return f"{round(seconds, 3):.3f}".rstrip("0").rstrip(".")


def say_replaced(files: OutputSet, earlier_until: float | None = None, hints: bool = True) -> None:
    """One line per earlier file that the switch kept under another name or removed (with the option that
    records one, if ``hints``)."""
    for old, new in files.kept:
        shows = f" (it shows the run up to {seconds_label(earlier_until)} s)" if earlier_until is not None else ""
        print(f"kept the earlier {old.name} as {new.name}{shows}")
    options = {suffix: option for suffix, _, option in RECORDINGS}
    for path in files.removed:
        add = f" (add {options[path.suffix]} to record one)" if hints and path.suffix in options else ""
        print(f"removed the earlier {path.name}: it showed the run that this one replaces{add}")


def finish(sim: Simulation, files: OutputSet, stem: str, wall: float, extra: dict, resumed: bool = False) -> dict:
    """Stage the checkpoint, picture and summary row of a finished run; return the row (and warn when the
    board overlaps a lot or dots left it). The row replaces the set's earlier row; a ``resumed`` run's keeps
    the earlier row's other fields (the parameters it was started with)."""
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
    row = {
        **extra,
        "engine": sim.settings.kind,
        "dots": summary["n_dots"],
        "time_s": round(state.time, 9),
        "steps": sim.steps_taken,
        "wall_s": round(wall, 3),
        "x_real_time": round(sim.steps_taken * sim.dt / wall, 3) if wall > 0 else float("nan"),
        "interior_fraction": summary["interior_fraction"],
        "mean_neighbours_interior": summary["mean_neighbours_interior"],
        OVERLAP_COLUMN: 100 * summary["max_overlap"],
        "escaped_dots": summary["escaped_dots"],
        # event engine: frames of this run that reached max_events (their rest unmoved, as the thesis's loop)
        "capped_frames": getattr(sim.engine, "capped_frames", ""),
        "kinetic_energy": summary["kinetic_energy"],
        "state_file": f"{stem}.npz",
    }
    files.update("summary.csv", lambda current, staged: merge_summary(current, [row], staged, keep_earlier=resumed))
    return row


def _upgrade(row: dict) -> dict:
    """A row of a table written before 0.3: its ``max_overlap`` (a fraction) as `OVERLAP_COLUMN` (percent)."""
    if "max_overlap" not in row:
        return row
    row = dict(row)
    old = row.pop("max_overlap")
    if not row.get(OVERLAP_COLUMN):
        try:
            row[OVERLAP_COLUMN] = repr(100 * float(old)) if old != "" else ""
        except ValueError:
            row[OVERLAP_COLUMN] = old
    return row


def merge_summary(path: Path, rows: Sequence[dict], into: Path | None = None, keep_earlier: bool = True) -> Path:
    """Add ``rows`` to the CSV at ``path``, replacing earlier rows of the same ``state_file``; write the
    table to ``into`` (default ``path``).

    Earlier rows of other runs are kept (a resume never loses a preset's
    table), a replaced row keeps the fields the new one does not set when ``keep_earlier`` (a resume keeps
    the parameters its run was started with; a new run replaces the row whole), and the
    columns are the union, in order of first appearance (a ``max_overlap`` column of an
    earlier version, a fraction, becomes `OVERLAP_COLUMN`, percent). An unreadable earlier
    table is set aside as ``summary.csv.unreadable`` (with a warning), not lost. Concurrent
    runs call this under the directory's lock (`labrig.files.OutputSet.update`).
    """
    into = path if into is None else into
    old = []
    if path.exists():
        try:
            with open(path, newline="", encoding="utf-8") as stream:
                old = [_upgrade(row) for row in csv.DictReader(stream)
                       if None not in row and None not in row.values()]
        except (OSError, UnicodeDecodeError, csv.Error) as exc:
            kept = path.with_name(path.name + ".unreadable")
            path.replace(kept)
            print(f"warning: {path} could not be read ({exc}); kept as {kept}, starting a new table", file=sys.stderr)
    previous = {row.get("state_file"): row for row in old}
    fresh = {row["state_file"] for row in rows}
    # a resumed run keeps the parameters its earlier row recorded
    merged = [row for row in old if row.get("state_file") not in fresh] + [
        {**(previous.get(row["state_file"], {}) if keep_earlier else {}), **row} for row in rows]
    columns = list(dict.fromkeys(key for row in merged for key in row))
    return write_csv(into, [{key: row.get(key, "") for key in columns} for row in merged])


def report(rows: Sequence[dict], out: Path) -> None:
    """Print the table of each finished run (their summary rows are already in ``out/summary.csv``)."""
    for row in rows:
        print_table(f"{row.get('name', row['state_file'])}:", [
            ("dots", str(row["dots"]) + (f" ({row['escaped_dots']} left the board)" if row["escaped_dots"] else "")),
            ("simulated time", f"{row['time_s']:.2f} s ({row['steps']} steps, {row['engine']} engine)"),
            ("wall time", f"{row['wall_s']:.1f} s ({row['x_real_time']:.1f}x real time)"),
            ("interior fraction", f"{row['interior_fraction']:.3f}"),
            ("mean neighbours (interior)", f"{row['mean_neighbours_interior']:.2f}"),
            ("max overlap", f"{row[OVERLAP_COLUMN]:.3f} % of radius"),
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
        with OutputSet(out, stem) as files:  # locks the set before anything is computed
            sim = build_simulation(exp)
            _recorders(files, sim, stem, movie, gsd)
            populate(sim, exp, progress=progress)
            rows.append(finish(sim, files, stem, time.perf_counter() - start,
                               {"name": exp.name, "seed": exp.seed, "sigma": exp.deposition.sigma,
                                "mass_model": exp.deposition.mass_model, "grating_px": exp.grating}))
            save_experiment(exp, files.stage(files.name_beside(f"{stem}.toml", source), last=True))
        say_replaced(files)
    report(rows, out)
    return rows


def resume(state_path: Path, seconds: float, out: Path | None, *, movie: bool, gsd: bool) -> dict:
    """Continue a saved run for ``seconds``; the new set replaces the old one unless ``out`` is another directory
    (`RESUME_RULE`).

    The old files are replaced only once the continuation has finished and its files are written.
    """
    if not state_path.exists():  # before the output set makes ``out``
        raise FileNotFoundError(f"no such qdots state file: {state_path}")
    out = state_path.parent if out is None else out
    stem = state_path.stem
    in_place = (out / state_path.name).exists() and (out / state_path.name).samefile(state_path)
    start = time.perf_counter()
    with OutputSet(out, stem) as files:  # locks the set before the state is read
        sim = checkpoint.load(state_path)
        earlier_until = sim.time if in_place else None
        _recorders(files, sim, stem, movie, gsd, earlier_until)
        sim.run(seconds, progress=True)
        row = finish(sim, files, stem, time.perf_counter() - start, {"resumed_from": str(state_path)},
                     resumed=True)
    say_replaced(files, earlier_until)
    report([row], out)
    return row


def render(state_path: Path, png: Path | None) -> Path:
    """Picture of a saved board."""
    from ..render import save_png

    png = state_path.with_suffix(".png") if png is None else png
    replaced = png.exists()
    save_png(checkpoint.read_state(state_path), png)
    print(f"wrote {png}" + (" (replaced the earlier picture of that name)" if replaced else ""))
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
