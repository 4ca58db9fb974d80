"""Running a sweep: local processes or a Dask cluster, one record file per run, resumable.

Layout of an output directory::

    out/sweep.json          what was swept (runner kind, swept columns, run ids), for sweep-plot
    out/runs/<id>.json      one record per finished run: parameters, row or error, attempts, wall time
    out/states/<id><suffix> the run's final state, when asked for
    out/table.csv           every run of the sweep, one row each (and table.parquet with pyarrow)

Every file is written atomically: a record by the process that drives the
sweep as soon as its run ends, a state file by the worker that ran it. A
sweep killed at any moment loses only the runs in progress, and running it
again skips every run that has a record with status ``"ok"`` (and its state
file, if states are asked for); failed runs are tried again. A run whose code raises is
tried ``retries`` more times, then recorded as failed with its error and
traceback; the sweep goes on. A local worker process that dies (a crash, a
kill) takes down the runs in flight with it: those are re-run one at a time,
and the one that kills its worker alone is charged an attempt. On Dask the
scheduler itself reruns the tasks of a lost worker (up to its
``allowed-failures``); a run it gives up on (``KilledWorker``) is charged an
attempt.
"""

from __future__ import annotations

import json
import os
import pickle
import time
import traceback
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from ..files import writable_directory, write_text_atomic
from ..validate import InputError, count
from .backends import LocalPool, make_backend
from .spec import DEFAULT_MAX_RUNS, Run, Sweep
from .table import table_rows, write_table

#: Format tag and version of the per-run record files.
RECORD_FORMAT = "labrig-sweep-run"
#: Record formats read as this one (sweeps written before the rig had its own name).
RECORD_FORMATS = (RECORD_FORMAT, "qdots-sweep-run")
RECORD_VERSION = 1
#: Most extra attempts of a failing run.
MAX_RETRIES = 100
#: Columns a run's row may not use (the sweep's own columns).
RESERVED = ("run", "status", "label", "wall_s", "attempts", "error", "state_file")


@dataclass(frozen=True)
class FunctionRunner:
    """A plain ``run_one(params) -> dict`` (or ``run_one(params, state_path)``) as a runner.

    Its parameters are taken as they are (no defaults filled in); its kind,
    part of every run's hash, is the function's qualified name.
    """

    function: Callable
    state_suffix: str = ".npz"

    @property
    def kind(self) -> str:
        return f"{self.function.__module__}.{self.function.__qualname__}"

    def canonical(self, params: dict) -> dict:
        return json.loads(json.dumps(params, allow_nan=False))

    def __call__(self, params: dict, state_path: Path | None = None) -> dict:
        return self.function(params) if state_path is None else self.function(params, state_path)


def as_runner(run_one):
    """``run_one`` itself if it has ``canonical`` and ``kind``, else a `FunctionRunner` around it."""
    if hasattr(run_one, "canonical") and hasattr(run_one, "kind"):
        return run_one
    if not callable(run_one):
        raise TypeError(f"run_one must be callable, got {type(run_one).__name__}")
    return FunctionRunner(run_one)


@dataclass
class SweepResult:
    """What `run_sweep` did: the gathered table and counts."""

    rows: list
    table: Path
    parquet: Path | None
    ran: int
    skipped: int
    failed: int

    def __repr__(self) -> str:
        return (f"SweepResult({len(self.rows)} runs: {self.ran} ran, {self.skipped} already done, "
                f"{self.failed} failed; table {self.table})")


def _plain(key: str, value):
    if hasattr(value, "item") and getattr(value, "ndim", None) == 0:  # numpy scalars
        value = value.item()
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    raise TypeError(f"row value {key!r} must be a number, string, boolean or None, got {type(value).__name__}")


def _check_row(row) -> dict:
    if not isinstance(row, dict):
        raise TypeError(f"run_one must return a dict (one table row), got {type(row).__name__}")
    clash = [k for k in row if k in RESERVED]
    if clash:
        raise InputError(f"row key {clash[0]!r} is reserved for the sweep table ({', '.join(RESERVED)})")
    return {str(key): _plain(key, value) for key, value in row.items()}


def execute_run(runner, params: dict, state_path: str | None) -> dict:
    """Run one attempt in a worker; the outcome as a dict (exceptions caught, with their traceback)."""
    start = time.perf_counter()
    try:
        row = _check_row(runner(params, None if state_path is None else Path(state_path)))
        return {"status": "ok", "row": row, "wall_s": time.perf_counter() - start}
    except Exception as exc:  # the sweep records it and goes on
        return {"status": "failed", "error": f"{type(exc).__name__}: {exc}", "traceback": traceback.format_exc(),
                "wall_s": time.perf_counter() - start}


def record_path(out: Path, run: Run) -> Path:
    return Path(out) / "runs" / f"{run.id}.json"


def read_record(out: Path, run: Run) -> dict | None:
    """The record of ``run`` in ``out``, or None if there is none (or it is unreadable, refused by
    `labrig.jsonfile.read_json`, e.g. nested too deep, or another run's)."""
    from ..jsonfile import read_json

    try:
        record = read_json(record_path(out, run), "sweep record")
    except (OSError, ValueError):  # InputError among them
        return None
    ok = isinstance(record, dict) and record.get("format") in RECORD_FORMATS and record.get("id") == run.id
    return record if ok else None


def _write_json(path: Path, data: dict) -> None:
    write_text_atomic(path, json.dumps(data, indent=1))


def _well_formed(record: dict) -> bool:
    """Whether a finished record holds what the table needs: a row of plain values, its attempts and wall time."""
    row, wall = record.get("row"), record.get("wall_s")
    plain = (type(None), bool, int, float, str)
    return (isinstance(row, dict) and all(isinstance(k, str) and isinstance(v, plain) for k, v in row.items())
            and isinstance(record.get("attempts"), int) and not isinstance(record.get("attempts"), bool)
            and (wall is None or (isinstance(wall, (int, float)) and not isinstance(wall, bool))))


def _finished(out: Path, run: Run, state_suffix: str | None) -> dict | None:
    """The record of a run that finished well, or None (to run it again: missing, failed or damaged)."""
    record = read_record(out, run)
    if record is None or record.get("status") != "ok" or not _well_formed(record):
        return None
    if state_suffix is not None and not (out / "states" / f"{run.id}{state_suffix}").is_file():
        return None
    return record


def _progress(total: int, done: int, show: bool):
    from tqdm.auto import tqdm

    return tqdm(total=total, initial=done, unit="run", desc="sweep", disable=not show, dynamic_ncols=True)


def output_directory(out: str | os.PathLike) -> Path:
    """``out`` as an absolute, normalised directory path, created if missing; `InputError` when something else is
    there (a file, or a symbolic link to nothing)."""
    out = writable_directory(os.path.abspath(out))
    out.mkdir(parents=True, exist_ok=True)
    return out


def describe_plan(sweep: Sweep, runs: list, todo: int, capacity: int, estimate) -> str:
    """One line saying what a sweep is about to do: its runs, how many are left, on how many workers, and about
    how long that takes when the runner can estimate a run (``estimate(params) -> seconds``)."""
    factors = " x ".join(f"{n:,} {key}" for key, n in sweep.shape().items() if n > 1) or "1 run"
    line = (f"{len(runs):,} runs ({factors}): {len(runs) - todo:,} finished before, {todo:,} to run "
            f"on {capacity} worker{'s' if capacity > 1 else ''}")
    if todo and estimate is not None:
        seconds = sum(estimate(run.params) for run in runs) * todo / len(runs) / capacity
        from ..progress import duration  # (the progress module imports numba's event hooks: only when needed)

        line += f", about {duration(seconds)} (a rough estimate; the progress bar's ETA follows the runs)"
    return line


def run_sweep(sweep: Sweep, run_one, out: str | os.PathLike, *, workers: int | None = None, scheduler=None,
              retries: int = 1, state: bool = False, progress: bool = True,
              max_runs: int = DEFAULT_MAX_RUNS) -> SweepResult:
    """Run every unfinished run of ``sweep``, then write the table of all of them.

    Parameters
    ----------
    sweep : Sweep
    run_one : callable or runner
        ``run_one(params) -> dict``: one run, returning its table row (numbers,
        strings, booleans). With ``state=True`` it is called as
        ``run_one(params, state_path)`` and writes the run's final state there.
        A runner object may also have ``kind`` (str, part of every run's hash),
        ``canonical(params) -> params`` (validates and fills in defaults) and
        ``state_suffix``. It must be picklable (a module-level function or
        class instance) to run in other processes.
    out : path
        Output directory (see the module docstring); created if missing.
    workers : int, optional
        Local worker processes (default: every core this process may use);
        1 runs in this process.
    scheduler : str or distributed.Client, optional
        Run on this Dask cluster instead (an address such as
        ``"tcp://10.0.0.5:8786"``, or a client). Workers write the state files:
        with ``state=True`` they need the output directory on a shared file system.
    retries : int
        Extra attempts for a run that raises (>= 0; default 1).
    state : bool
        Keep each run's final state in ``out/states``.
    progress : bool
        Say what is about to run (runs, workers, output directory, an estimate of the time when the runner has an
        ``estimate(params) -> seconds``), then one progress bar over the runs (done / total, ETA).
    max_runs : int
        Most runs the sweep may have (default `DEFAULT_MAX_RUNS`, at most `MAX_RUNS`): a larger sweep is refused
        before anything runs.

    Returns
    -------
    SweepResult
        With ``rows``, the table: one row per run in the sweep's order, with
        ``run``, ``status``, the swept columns, the runner's row, ``wall_s``,
        ``attempts``, ``error``, ``state_file`` and every other parameter.
        Equal sweeps give equal tables (up to ``wall_s``), whatever the
        executor, the number of workers and the order in which runs finish.
    """
    runner = as_runner(run_one)
    retries = count("retries", retries, 0, MAX_RETRIES)
    sweep.check_size(max_runs)
    out = output_directory(out)
    runs = sweep.runs(runner.canonical, runner.kind)
    (out / "runs").mkdir(exist_ok=True)
    suffix = getattr(runner, "state_suffix", ".npz") if state else None
    if state:
        (out / "states").mkdir(exist_ok=True)
    _write_json(out / "sweep.json", {"format": "labrig-sweep", "version": 1, "kind": runner.kind,
                                     "swept": sweep.swept, "seed_key": sweep.seed_key,
                                     "runs": [run.id for run in runs]})
    records = {run.id: _finished(out, run, suffix) for run in runs}
    todo = deque((run, 0) for run in runs if records[run.id] is None)
    skipped = len(runs) - len(todo)
    backend = make_backend(workers, scheduler)
    if isinstance(backend, LocalPool):
        try:
            pickle.dumps(runner)
        except Exception as exc:
            raise InputError(f"run_one must be picklable to run in worker processes (define it at module "
                             f"level), or use workers=1: {exc}") from None
    if progress:
        print(f"sweep: {describe_plan(sweep, runs, len(todo), backend.capacity, getattr(runner, 'estimate', None))}; "
              f"output: {out}", flush=True)
    bar = _progress(len(runs), skipped, progress)
    try:
        _drive(backend, runner, out, suffix, todo, records, retries, bar)
    finally:
        bar.close()
        backend.close()
    rows = table_rows(runs, [records[run.id] for run in runs])
    table, parquet = write_table(rows, out)
    failed = sum(row["status"] != "ok" for row in rows)
    return SweepResult(rows, table, parquet, len(runs) - skipped, skipped, failed)


def _drive(backend, runner, out: Path, suffix, todo: deque, records: dict, retries: int, bar) -> None:
    """Submit, collect and record runs until none is left."""
    suspects: deque = deque()  # runs in flight when a worker process died: re-run one at a time
    inflight: dict = {}
    failed: list = []

    def submit(run: Run, attempts: int, alone: bool) -> None:
        state_path = None if suffix is None else str((out / "states" / f"{run.id}{suffix}").resolve())
        inflight[backend.submit(execute_run, runner, run.params, state_path)] = (run, attempts, alone)

    def finish(run: Run, attempts: int, outcome: dict) -> None:
        record = {"format": RECORD_FORMAT, "version": RECORD_VERSION, "id": run.id, "kind": runner.kind,
                  "index": run.index, "columns": run.columns, "params": run.params, "attempts": attempts,
                  "state_file": f"states/{run.id}{suffix}" if suffix and outcome["status"] == "ok" else None,
                  **outcome}
        _write_json(record_path(out, run), record)
        records[run.id] = record
        bar.update(1)
        if outcome["status"] != "ok":
            failed.append(run.id)
            bar.set_postfix(failed=len(failed))

    try:
        _loop(backend, todo, suspects, inflight, submit, finish, retries)
    except BaseException:  # interrupted: stop what was sent off; finished runs are on disk already
        backend.cancel(list(inflight))
        raise


def _loop(backend, todo: deque, suspects: deque, inflight: dict, submit, finish, retries: int) -> None:
    while todo or suspects or inflight:
        if suspects:
            if not inflight:
                submit(*suspects.popleft()[:2], alone=True)
        else:
            while todo and len(inflight) < backend.capacity:
                submit(*todo.popleft(), alone=False)
        done = backend.wait(list(inflight))
        for future in sorted(done, key=lambda f: f.exception() is not None):  # results before a crash
            if future not in inflight:  # already taken down with a crashed pool
                continue
            run, attempts, alone = inflight.pop(future)
            try:
                outcome = future.result()
            except Exception as exc:
                if backend.crashed(exc):
                    lost = [(run, attempts, alone)] + list(inflight.values())
                    inflight.clear()
                    if not alone:  # cannot tell which run killed the worker: try each alone
                        suspects.extend(lost)
                        break
                    outcome = {"status": "failed", "error": f"the worker process died ({type(exc).__name__}: "
                                                            f"{exc})", "traceback": None, "wall_s": None}
                else:
                    outcome = {"status": "failed", "error": f"{type(exc).__name__}: {exc}",
                               "traceback": "".join(traceback.format_exception(exc)), "wall_s": None}
            attempts += 1
            if outcome["status"] == "ok" or attempts > retries:
                finish(run, attempts, outcome)
            elif alone:
                suspects.appendleft((run, attempts, True))
            else:
                todo.appendleft((run, attempts))
