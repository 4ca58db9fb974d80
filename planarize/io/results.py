"""Saving and loading runs: one ``.npz`` per `Anodization`, and its history as CSV or JSON.

Run files (``format = "planarize-run"``, ``version = 1``) are NumPy ``.npz``
archives with the arrays

* ``initial``, ``metal``, ``oxide`` (nx, ny) nm and ``distances`` (nx, ny) nm,
* ``history_<column>`` for each history column (`planarize.metrics.HISTORY_COLUMNS`),
* ``snapshot_target``, ``snapshot_thickness`` (S,) nm and ``snapshot_metal``,
  ``snapshot_oxide``, ``snapshot_distances`` (S, nx, ny) nm,
* ``metadata``: one JSON string with ``format``, ``version``, the grid
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

from labrig.files import atomic_path, write_csv, write_text_atomic
from labrig.validate import InputError

from ..anodize import Anodization, Snapshot
from ..surface import Surface

FORMAT = "planarize-run"
VERSION = 1


def save_run(run: Anodization, path: str | os.PathLike) -> Path:
    """Write ``run`` to ``path`` (.npz), atomically; returns the path."""
    if not isinstance(run, Anodization):
        raise TypeError(f"run must be a planarize.Anodization, got {type(run).__name__}")
    grid = run.initial
    metadata = {"format": FORMAT, "version": VERSION, "spacing": list(grid.spacing), "boundary": grid.boundary,
                "history_columns": list(run.history), "parameters": run.parameters}
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
        "metadata": np.array(json.dumps(metadata)),
    }
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as stream:
            np.savez(stream, **arrays)
    return Path(path)


def load_run(path: str | os.PathLike) -> Anodization:
    """Read a run file written by `save_run`.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        If it is not a readable planarize run file; the message starts with the path.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"run file {str(path)!r} does not exist")
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {key: data[key] for key in data.files}
        metadata = json.loads(str(arrays.pop("metadata")))
        if metadata.get("format") != FORMAT:
            raise InputError(f"not a planarize run file (format {metadata.get('format')!r})")
        if metadata.get("version") != VERSION:
            raise InputError(f"unsupported run file version {metadata.get('version')!r} (this is {VERSION})")
        spacing, boundary = tuple(metadata["spacing"]), metadata["boundary"]

        def surface(z) -> Surface:
            return Surface(z, spacing, boundary)

        snapshots = [Snapshot(float(t), float(h), surface(m), surface(o), d) for t, h, m, o, d in zip(
            arrays["snapshot_target"], arrays["snapshot_thickness"], arrays["snapshot_metal"],
            arrays["snapshot_oxide"], arrays["snapshot_distances"])]
        history = {key: arrays[f"history_{key}"] for key in metadata["history_columns"]}
        distances = arrays["distances"]
        return Anodization(metadata["parameters"], history, snapshots, surface(arrays["initial"]),
                           surface(arrays["metal"]), surface(arrays["oxide"]),
                           None if np.isnan(distances).all() else distances)
    except (OSError, ValueError, KeyError, TypeError, EOFError) as exc:
        raise InputError(f"{path}: cannot read the run file: {exc}") from None


def save_history_csv(run: Anodization, path: str | os.PathLike) -> Path:
    """The history table as CSV (one row per recorded thickness), atomically."""
    return write_csv(Path(path), run.rows())


def history_json(run: Anodization) -> dict:
    """The run's parameters, column descriptions and history as a strict-JSON-ready dict (inf/nan -> None)."""
    from ..metrics import HISTORY_COLUMNS

    def clean(v):
        return None if isinstance(v, float) and not math.isfinite(v) else v

    return {"parameters": run.parameters,
            "columns": {key: HISTORY_COLUMNS.get(key, "") for key in run.history},
            "history": {key: [clean(v.item()) for v in values] for key, values in run.history.items()}}


def save_history_json(run: Anodization, path: str | os.PathLike) -> Path:
    """`history_json` written to ``path``, atomically."""
    return write_text_atomic(path, json.dumps(history_json(run), indent=1, allow_nan=False) + "\n")
