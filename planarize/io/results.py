"""Saving and loading runs: one ``.npz`` per `Anodization`, and its history as CSV or JSON.

Run files (``format = "planarize-run"``, ``version = 1``) are NumPy ``.npz``
archives with the arrays

* ``initial``, ``metal``, ``oxide`` (nx, ny) nm and ``distances`` (nx, ny) nm,
* ``history_<column>`` for each history column (`planarize.metrics.HISTORY_COLUMNS`),
* ``snapshot_target``, ``snapshot_thickness`` (S,) nm and ``snapshot_metal``,
  ``snapshot_oxide``, ``snapshot_distances`` (S, nx, ny) nm,
* ``metadata``: one JSON string with ``format``, ``version`` (of the file format), ``planarize`` (the
  package version that wrote it, so that a file says which behaviour made it), the grid
  (``spacing``, ``boundary``), the history column order and the run's
  ``parameters``.

Any NumPy reads them. Every file is written atomically.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np

from labrig import __version__
from labrig.archive import MAX_ARCHIVE_BYTES, read_archive, write_archive
from labrig.files import recover_beside, write_csv, write_text_atomic
from labrig.validate import InputError, choice, reals

from ..anodize import MAX_RECORD, Anodization, Snapshot
from ..heightfield import BOUNDARIES, MAX_POINTS, Surface

FORMAT = "planarize-run"
VERSION = 1
#: Arrays every run file holds.
ARRAYS = ("initial", "metal", "oxide", "distances", "snapshot_target", "snapshot_thickness", "snapshot_metal",
          "snapshot_oxide", "snapshot_distances")
#: Largest size of each saved array, bytes (float64 or int64 values): a grid of at most
#: `planarize.heightfield.MAX_POINTS` points, a history column or snapshot list of at most
#: `planarize.anodize.MAX_RECORD` rows plus the first and the last, and the snapshots' grids (bounded by the
#: archive's total and the memory available; `labrig.archive.read_archive` refuses a file that declares more).
GRID_BYTES = MAX_POINTS * 8
SERIES_BYTES = (MAX_RECORD + 2) * 8
MAX_ARRAY_BYTES = {"initial": GRID_BYTES, "metal": GRID_BYTES, "oxide": GRID_BYTES, "distances": GRID_BYTES,
                   "history_*": SERIES_BYTES, "snapshot_target": SERIES_BYTES, "snapshot_thickness": SERIES_BYTES,
                   "snapshot_metal": MAX_ARCHIVE_BYTES, "snapshot_oxide": MAX_ARCHIVE_BYTES,
                   "snapshot_distances": MAX_ARCHIVE_BYTES}


def save_run(run: Anodization, path: str | os.PathLike) -> Path:
    """Write ``run`` to ``path`` (.npz), atomically; returns the path."""
    if not isinstance(run, Anodization):
        raise InputError(f"run must be a planarize.Anodization, got {type(run).__name__}")
    grid = run.initial
    metadata = {"format": FORMAT, "version": VERSION, "planarize": __version__, "spacing": list(grid.spacing),
                "boundary": grid.boundary, "history_columns": list(run.history), "parameters": run.parameters,
                "complete": run.complete}
    shots = run.snapshots
    empty = np.zeros((0, *grid.shape))
    arrays = {
        "initial": grid.z, "metal": run.metal.z, "oxide": run.oxide.z,
        "distances": np.full(grid.shape, np.nan) if run.distances is None else run.distances,
        **{f"history_{key}": np.asarray(values) for key, values in run.history.items()},
        "snapshot_target": np.array([s.target for s in shots], dtype=float),
        "snapshot_thickness": np.array([s.thickness for s in shots], dtype=float),
        "snapshot_metal": np.array([s.metal.z for s in shots]) if shots else empty,
        "snapshot_oxide": np.array([s.oxide.z for s in shots]) if shots else empty,
        "snapshot_distances": np.array([s.distances for s in shots]) if shots else empty,
    }
    return write_archive(path, metadata, arrays)


def load_run(path: str | os.PathLike) -> Anodization:
    """Read a run file written by `save_run`.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    labrig.validate.InputError
        If it is not a readable planarize run file (truncated, corrupted, another format or version,
        arrays of the wrong shape, bad metadata); the message starts with the path.
    """
    recover_beside(path)  # finish a switch of its output set that a kill interrupted (labrig.staging)
    metadata, arrays = read_archive(path, FORMAT, VERSION, ARRAYS, "planarize run", max_bytes=MAX_ARRAY_BYTES)
    try:
        spacing = reals("spacing", metadata.get("spacing"), 2)
        boundary = choice("boundary", metadata.get("boundary"), BOUNDARIES)
        columns = metadata.get("history_columns")
        if not (isinstance(columns, list) and all(isinstance(c, str) for c in columns)):
            raise InputError(f"history_columns must be a list of names, got {columns!r}")
        if not isinstance(metadata.get("parameters"), dict):
            raise InputError(f"parameters must be a table, got {metadata.get('parameters')!r}")

        def surface(z) -> Surface:
            return Surface(z, spacing, boundary)

        initial = surface(arrays["initial"])
        shape = initial.shape
        for name in ("metal", "oxide", "distances"):
            if arrays[name].shape != shape:
                raise InputError(f"{name} has shape {arrays[name].shape}, the initial surface {shape}")
        k = len(arrays["snapshot_target"])
        for name in ("snapshot_metal", "snapshot_oxide", "snapshot_distances"):
            if arrays[name].shape != (k, *shape):
                raise InputError(f"{name} has shape {arrays[name].shape}, expected {(k, *shape)}")
        snapshots = [Snapshot(float(t), float(h), surface(m), surface(o), d) for t, h, m, o, d in zip(
            arrays["snapshot_target"], arrays["snapshot_thickness"], arrays["snapshot_metal"],
            arrays["snapshot_oxide"], arrays["snapshot_distances"])]
        missing = [c for c in columns if f"history_{c}" not in arrays]
        if missing:
            raise InputError(f"no history column {missing[0]!r}")
        history = {key: arrays[f"history_{key}"] for key in columns}
        if len({len(v) for v in history.values()}) > 1:
            raise InputError("the history columns have different lengths")
        distances = arrays["distances"]
        return Anodization(metadata["parameters"], history, snapshots, initial, surface(arrays["metal"]),
                           surface(arrays["oxide"]), None if np.isnan(distances).all() else distances,
                           bool(metadata.get("complete", True)))
    except InputError as exc:
        raise InputError(f"{path}: the saved run is invalid: {exc}") from None


def save_history_csv(run: Anodization, path: str | os.PathLike) -> Path:
    """The history table as CSV (one row per recorded thickness), atomically."""
    return write_csv(Path(path), run.rows())


def history_json(run: Anodization) -> dict:
    """The run's parameters, column descriptions and history as a strict-JSON-ready dict (inf/nan -> None)."""
    from ..metrics import HISTORY_COLUMNS

    def clean(v):
        if isinstance(v, dict):
            return {key: clean(value) for key, value in v.items()}
        if isinstance(v, (list, tuple)):
            return [clean(value) for value in v]
        return None if isinstance(v, float) and not math.isfinite(v) else v

    return {"parameters": clean(run.parameters),
            "columns": {key: HISTORY_COLUMNS.get(key, "") for key in run.history},
            "history": {key: [clean(v.item()) for v in values] for key, values in run.history.items()}}


def save_history_json(run: Anodization, path: str | os.PathLike) -> Path:
    """`history_json` written to ``path``, atomically."""
    return write_text_atomic(path, json.dumps(history_json(run), indent=1, allow_nan=False) + "\n")
