"""What the ``qdots`` subcommands do; `qdots.cli.main` parses arguments and calls these.

Every command that runs dots writes, per experiment, a folder ``<slug>/`` into its output directory:
``<slug>.npz`` (final checkpoint, resumable), ``<slug>.png``, optionally ``<slug>.mp4`` and
``<slug>.gsd``, and the experiment file ``<slug>.toml`` for provenance; and a row of the directory's
``summary.csv``, the table of its runs. A run's folder is one `labrig.outputset.OutputSet`: locked when
the run starts (a second run of the same name into the same directory is refused), written when the
run has finished and switched into place in one atomic step, so that a run that fails or is killed
at any moment leaves the earlier folder of the same name whole, byte for byte. The table is rewritten
just after the switch (a kill in between leaves it one run behind). The experiment file a run was
started from is never written over (its provenance copy is then ``<slug>.ran.toml``). A board the
engine produced is always saved; its worst overlap and the dots that left an open board are
measured, printed as a warning when large, and recorded in the summary.

A new run replaces the folder of its name; an earlier ``<slug>.mp4`` or ``<slug>.gsd`` that it does
not rewrite, and the ``<slug>.until-Ts.mp4`` / ``.gsd`` that in-place resumes kept, are removed with
the rest (they showed the run whose state is gone), and the command says so. A resume writes a new
folder beside its input (`qdots.cli.main.RESUME_RULE`).
"""

from __future__ import annotations

import csv
import os
import re
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from labrig.cli import print_table
from labrig.files import slug, write_csv
from labrig.outputset import OutputSet
from labrig.validate import InputError, printable

from ..analysis.packing import packing_summary
from ..io import checkpoint
from ..simulation import OVERLAP_WARNING, Simulation

#: Simulated time between movie frames, s.
FRAME_INTERVAL = 0.5
#: The summary's column of the worst overlap: percent of the pair's mean radius (what the terminal prints).
OVERLAP_COLUMN = "max_overlap_pct_radius"
#: The files a run records on request: suffix, what it is, its option.
RECORDINGS = ((".mp4", "movie", "--movie"), (".gsd", "trajectory", "--gsd"))


def _recorders(files: OutputSet, sim: Simulation, stem: str, movie: bool, gsd: bool,
               earlier_until: float | None = None, *, title: str = "", diameters=None) -> None:
    """Attach the requested movie and trajectory writers to ``sim``, as streams of the output set, and say what
    becomes of the set's earlier ones: kept as ``stem.until-Ts.SUFFIX`` when ``earlier_until`` (T, s) is
    given (a resume in place), else removed unless rewritten. The movie's frames are titled ``title`` and
    coloured over ``diameters`` (`qdots.render.MovieWriter`)."""
    every = max(1, round(FRAME_INTERVAL / sim.dt))
    if movie:
        from ..render import MovieWriter

        sim.attach(files.adopt(MovieWriter(files.stage(f"{stem}.mp4"), every=every, title=title,
                                           diameters=diameters)))
    if gsd:
        from ..io.trajectory import GSDWriter

        sim.attach(files.adopt(GSDWriter(files.stage(f"{stem}.gsd"), every=every, dt=sim.dt)))
    for suffix, _, _ in RECORDINGS:
        if earlier_until is None:
            files.drop(f"{stem}{suffix}")
        else:
            files.keep_as(f"{stem}{suffix}", f"{stem}.until-{seconds_label(earlier_until)}s{suffix}")
    if earlier_until is None and files.path.is_dir():  # the earlier parts of the replaced run's movies
        for name in sorted(os.listdir(files.path)):
            if re.fullmatch(re.escape(stem) + r"\.until-[0-9.]+s(?:-[0-9]+)?\.(mp4|gsd)", name):
                files.drop(name)


def seconds_label(seconds: float) -> str:
    """A time for a file name, s: ``20.0`` -> ``"20"``, ``0.1300000001`` -> ``"0.13"`` (to the ms)."""
    return f"{round(seconds, 3):.3f}".rstrip("0").rstrip(".")


#: What each neighbour rule of ``qdots analyze --rule`` means (`qdots.analysis.neighbour_edges`).
RULE_WORDS = {
    "text": "two dots whose surfaces are less than one mean radius apart (the thesis's text; --rule code: its program)",
    "code": "dot j of dot i when their centres are at most r_i + 2 r_j apart (the thesis's program; --rule text: "
            "its text)",
}
#: How a mass model reads in a title.
MASS_WORDS = {"equal": "equal masses", "area": "masses ~ d^2", "volume": "masses ~ d^3", "bimodal": "bimodal masses"}


def run_identity(exp) -> dict:
    """What says which run a picture shows: name, dots, sigma, mass model, engine and seed of ``exp``."""
    return {"name": exp.name, "dots": exp.deposition.n_dots, "sigma": exp.deposition.sigma,
            "mass_model": exp.deposition.mass_model, "engine": exp.engine.kind, "seed": exp.seed}


def run_title(identity: dict) -> str:
    """Two lines: the run's name, then what it is (the keys of `run_identity` that ``identity`` has)."""
    mass_model = identity.get("mass_model")
    parts = [f"{identity['dots']} dots" if "dots" in identity else None,
             f"sigma {identity['sigma']:g}" if "sigma" in identity else None,
             MASS_WORDS.get(mass_model, mass_model) if mass_model is not None else None,
             f"{identity['engine']} engine" if "engine" in identity else None,
             f"seed {identity['seed']}" if "seed" in identity else None]
    details = ", ".join(part for part in parts if part)
    name = printable(identity.get("name", ""))  # a title never holds a control character (matplotlib has no glyph)
    return f"{name}\n{details}" if details else name


def _identity_of(state_path: Path, sim: Simulation, name: str) -> dict:
    """The identity of the run saved in ``state_path`` (`run_identity`, as `finish` saves it), renamed ``name``;
    for a state saved without one, its dots and engine."""
    saved = checkpoint.read_metadata(state_path).get("run")
    saved = saved if isinstance(saved, dict) else {"dots": sim.n_dots, "engine": sim.engine.kind}
    return {**saved, "name": name}


def nominal_diameters(mean: float, sigma: float) -> tuple[float, float] | None:
    """The diameters, px, that a movie of a deposition of ``mean`` px diameter and spread ``sigma`` colours from
    first to last colour: the mean +- 3 standard deviations (None for equal sizes: the movie then takes each
    frame's)."""
    return (mean * max(1.0 - 3.0 * sigma, 0.01), mean * (1.0 + 3.0 * sigma)) if sigma > 0 else None


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


def finish(sim: Simulation, files: OutputSet, stem: str, wall: float, extra: dict, identity: dict,
           resumed: bool = False, colour_range: tuple[float, float] | None = None) -> dict:
    """Stage the checkpoint (with the run's ``identity``), picture (sizes coloured over ``colour_range``, px, as
    its movie's) and summary row of a finished run; return the row (and warn when the board overlaps a lot
    or dots left it). The row replaces the set's earlier row; a ``resumed`` run's keeps the earlier row's
    other fields (the parameters it was started with)."""
    from ..render import save_png

    state = sim.state()
    save_png(state, files.stage(f"{stem}.png"), title=run_title(identity), colour_range=colour_range)
    summary = packing_summary(state)
    checkpoint.save(sim, files.stage(f"{stem}.npz"), {"run": identity})
    if summary["max_overlap"] > OVERLAP_WARNING:
        print(f"warning: {stem}: dots overlap by up to {100 * summary['max_overlap']:.1f} % of a radius (more than "
              f"{100 * OVERLAP_WARNING:g} %): the time step is too large for these speeds", file=sys.stderr)
    if summary["escaped_dots"]:
        print(f"warning: {stem}: {summary['escaped_dots']} of {summary['n_dots']} dots have left the open board",
              file=sys.stderr)
    row = {
        **extra,
        "engine": sim.engine.kind,
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
        "capped_frames": sim.backend.diagnostics().get("capped_frames", ""),
        "kinetic_energy": summary["kinetic_energy"],
        "state_file": f"{stem}/{stem}.npz",
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


def _set_aside(path: Path, suffix: str) -> Path:
    """A copy of ``path`` as ``path.SUFFIX`` (``path.SUFFIX-2``, ... when taken); returns it."""
    import shutil

    kept, k = path.with_name(f"{path.name}.{suffix}"), 1
    while kept.exists():
        k += 1
        kept = path.with_name(f"{path.name}.{suffix}-{k}")
    shutil.copy2(path, kept)
    return kept


def read_summary(path: Path) -> list[dict]:
    """The rows of a summary table; [] if there is none. A table that cannot be read is kept as
    ``summary.csv.unreadable`` and one with rows of more or fewer cells than its header as ``summary.csv.ragged``
    (each with a warning naming the lines): its other rows are read, none is lost."""
    if not path.exists():
        return []
    try:
        with open(path, newline="", encoding="utf-8") as stream:
            reader = csv.DictReader(stream)
            rows, ragged = [], []
            for row in reader:
                if None in row or None in row.values():
                    ragged.append(reader.line_num)
                else:
                    rows.append(_upgrade(row))
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        kept = _set_aside(path, "unreadable")
        print(f"warning: {path} could not be read ({printable(exc)}); kept as {kept}, starting a new table",
              file=sys.stderr)
        return []
    if ragged:
        kept = _set_aside(path, "ragged")
        lines = ", ".join(map(str, ragged[:10])) + (" ..." if len(ragged) > 10 else "")
        print(f"warning: {path}: line{'s' if len(ragged) > 1 else ''} {lines} {'have' if len(ragged) > 1 else 'has'} "
              f"more or fewer cells than the header; the table is kept whole as {kept} and the new one has its "
              "other rows", file=sys.stderr)
    return rows


def merge_summary(path: Path, rows: Sequence[dict], into: Path | None = None, keep_earlier: bool = True) -> Path:
    """Add ``rows`` to the CSV at ``path``, replacing earlier rows of the same ``state_file``; write the
    table to ``into`` (default ``path``).

    Earlier rows of other runs are kept (a resume never loses a preset's
    table), a replaced row keeps the fields the new one does not set when ``keep_earlier`` (an in-place resume
    keeps the parameters its run was started with; a new run replaces the row whole), and the
    columns are the union, in order of first appearance (a ``max_overlap`` column of an
    earlier version, a fraction, becomes `OVERLAP_COLUMN`, percent). An earlier table that cannot be read
    whole is kept beside (`read_summary`). Concurrent runs call this under the directory's lock
    (`labrig.outputset.OutputSet.update`).
    """
    into = path if into is None else into
    old = read_summary(path)
    previous = {row.get("state_file"): row for row in old}
    fresh = {row["state_file"] for row in rows}
    merged = [row for row in old if row.get("state_file") not in fresh] + [
        {**(previous.get(row["state_file"], {}) if keep_earlier else {}), **row} for row in rows]
    columns = list(dict.fromkeys(key for row in merged for key in row))
    return write_csv(into, [{key: row.get(key, "") for key in columns} for row in merged])


def report(rows: Sequence[dict], out: Path, folders: Sequence[OutputSet]) -> None:
    """Print the table of each finished run and the files written (the rows are already in ``out/summary.csv``)."""
    for row, files in zip(rows, folders):
        print_table(f"{row.get('name', row['state_file'])}:", [
            ("dots", str(row["dots"]) + (f" ({row['escaped_dots']} left the board)" if row["escaped_dots"] else "")),
            ("simulated time", f"{row['time_s']:.2f} s ({row['steps']} steps, {row['engine']} engine)"),
            ("wall time", f"{row['wall_s']:.1f} s ({row['x_real_time']:.1f}x real time)"),
            ("interior fraction", f"{row['interior_fraction']:.3f}"),
            ("mean neighbours (interior)", f"{row['mean_neighbours_interior']:.2f}"),
            ("max overlap", f"{row[OVERLAP_COLUMN]:.3f} % of radius"),
            ("files", f"{files.path}{os.sep}: " + ", ".join(path.name for path in files.written)),
        ])
    runs = f"{len(rows)} run folders and their rows" if len(rows) != 1 else "1 run folder and its row"
    print(f"wrote {runs} in {out / 'summary.csv'}")


def run_experiments(experiments: Sequence, out: Path, *, movie: bool, gsd: bool, progress: bool = True,
                    source: Path | None = None) -> list[dict]:
    """Run each experiment, writing its folder into ``out``; returns the summary rows.

    ``source`` is the experiment file they were read from: it is never written over.
    """
    from ..experiment import build_simulation, populate
    from ..io.experiment_file import save_experiment

    rows, folders = [], []
    for exp in experiments:
        stem = slug(exp.name)
        start = time.perf_counter()
        with OutputSet(out, stem) as files:  # locks the set before anything is computed
            sim = build_simulation(exp)
            identity = run_identity(exp)
            colour_range = nominal_diameters(exp.deposition.mean_diameter, exp.deposition.sigma)
            _recorders(files, sim, stem, movie, gsd, title=run_title(identity), diameters=colour_range)
            populate(sim, exp, progress=progress)
            rows.append(finish(sim, files, stem, time.perf_counter() - start,
                               {"name": exp.name, "seed": exp.seed, "sigma": exp.deposition.sigma,
                                "mass_model": exp.deposition.mass_model, "grating_px": exp.grating}, identity,
                               colour_range=colour_range))
            save_experiment(exp, files.stage(files.name_beside(f"{stem}.toml", source)))
        say_replaced(files)
        folders.append(files)
    report(rows, out, folders)
    return rows


def continuation_name(stem: str, until: float) -> str:
    """The name of a continuation of the run ``stem`` that reaches ``until`` s: ``film`` -> ``film-t30s``, and
    ``film-t30s`` -> ``film-t40s`` (a continuation of a continuation)."""
    base = re.sub(r"-t[0-9.]+s$", "", stem) or stem
    return f"{base}-t{seconds_label(until)}s"


def home_of(state_path: Path) -> Path | None:
    """The output directory of the run folder that holds ``state_path`` (``OUT/NAME/NAME.npz`` -> ``OUT``), or None
    when the file is not in a folder of its name."""
    folder = state_path.parent
    if Path(os.path.abspath(folder)).name != state_path.stem:
        return None
    return folder.parent if folder.name else Path("..")


def _earlier_row(state_path: Path) -> dict:
    """The summary row of the run whose state is ``state_path``, from its directory's table ({} if none)."""
    home = home_of(state_path)
    table = (home if home is not None else state_path.parent) / "summary.csv"
    keys = {f"{state_path.stem}/{state_path.name}", state_path.name}
    try:
        with open(table, newline="", encoding="utf-8") as stream:
            found = [row for row in csv.DictReader(stream) if row.get("state_file") in keys]
    except (OSError, UnicodeDecodeError, csv.Error):
        return {}
    return {k: v for k, v in found[-1].items() if k is not None and v is not None} if found else {}


def resume(state_path: Path, seconds: float, out: Path | None, *, movie: bool, gsd: bool,
           in_place: bool = False) -> dict:
    """Continue a saved run for ``seconds``, into a new folder beside it, or into ``out``, or with ``in_place`` in
    its own folder (`qdots.cli.main.RESUME_RULE`). The input is never changed, except by ``in_place``, and then only once the
    continuation has finished and its files are written."""
    if not state_path.exists():  # before the output set makes ``out``
        raise FileNotFoundError(f"no such qdots state file: {state_path}")
    home = home_of(state_path)
    start = time.perf_counter()
    if in_place:
        if home is None:
            raise InputError(f"--in-place replaces the run's folder, but {state_path} is not in a folder of its name "
                             f"({state_path.stem}/{state_path.name}): resume it without --in-place")
        if out is not None:
            raise InputError("--in-place and --out exclude each other (--in-place writes into the run's own folder)")
        out, stem = home, state_path.stem
        files = OutputSet(out, stem)  # locks the set before the state is read
        with files:
            sim = checkpoint.load(state_path)
            identity = _identity_of(state_path, sim, stem)
            earlier_until = sim.time
            _recorders(files, sim, stem, movie, gsd, earlier_until, title=run_title(identity))
            sim.run(seconds, progress=True)
            row = finish(sim, files, stem, time.perf_counter() - start, {"resumed_from": str(state_path)}, identity,
                         resumed=True)
        say_replaced(files, earlier_until)
        print(f"resumed {state_path} in place: {files.path} now holds the run up to {seconds_label(sim.time)} s")
    else:
        if out is not None and home is not None and Path(os.path.realpath(out)).is_relative_to(
                os.path.realpath(state_path.parent)):
            raise InputError(f"--out {str(out)!r} is in the folder of the run {state_path.stem!r} itself: a "
                             "continuation is written beside it (without --out), or replaces it (--in-place)")
        sim = checkpoint.load(state_path)
        sim.check_run(seconds)  # before the continuation's name is made of the time it reaches
        stem = continuation_name(state_path.stem, sim.time + seconds)
        out = (home if home is not None else state_path.parent) if out is None else out
        identity = _identity_of(state_path, sim, stem)
        extra = {**_earlier_row(state_path), "name": stem, "resumed_from": str(state_path)}
        with OutputSet(out, stem) as files:
            _recorders(files, sim, stem, movie, gsd, title=run_title(identity))
            sim.run(seconds, progress=True)
            row = finish(sim, files, stem, time.perf_counter() - start, extra, identity)
        say_replaced(files)
        print(f"wrote the continuation as the new run {stem} in {files.path}; {state_path} is unchanged "
              "(--in-place replaces its folder instead)")
    report([row], out, [files])
    return row


def render(state_path: Path, png: Path | None) -> Path:
    """Picture of a saved board, titled with its run (`run_title` of what the state file records, else its name)."""
    from ..render import save_png

    png = state_path.with_suffix(".png") if png is None else png
    replaced = png.exists()
    saved = checkpoint.read_metadata(state_path).get("run")
    title = run_title(saved) if isinstance(saved, dict) else printable(state_path.stem)
    save_png(checkpoint.read_state(state_path), png, title=title)
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
        print_table(f"{state_path} at t = {state.time:.2f} s:",
                    [("neighbours", RULE_WORDS[rule])] + table_rows(summary))
        if plot is not None:
            print(f"wrote {plot}")
    return summary
