"""The table of a sweep: one row per run, every parameter a column; CSV, and Parquet with pyarrow."""

from __future__ import annotations

import csv
import json
import math
import os
from pathlib import Path
from typing import Sequence

from ..files import atomic_path, existing_file, write_csv
from ..validate import InputError, printable

#: Largest table read, bytes.
MAX_TABLE_BYTES = 2**30


def flatten(params, prefix: str = "") -> dict:
    """Nested parameters as one level of dotted keys; lists of tables are indexed (``forces.0.r0``).

    Lists of plain values become their JSON text (one cell).
    """
    flat = {}
    items = params.items() if isinstance(params, dict) else enumerate(params)
    for key, value in items:
        name = f"{prefix}{key}"
        if isinstance(value, dict) or (isinstance(value, list) and value and all(isinstance(v, dict) for v in value)):
            flat.update(flatten(value, f"{name}."))
        else:
            flat[name] = _cell(value)
    return flat


def _cell(value):
    return json.dumps(value) if isinstance(value, (list, dict)) else value


def table_rows(runs: Sequence, records: Sequence[dict | None]) -> list[dict]:
    """One row per run (in the sweep's order): identity, swept columns, results, bookkeeping, parameters.

    A run without a record (not run yet) gets status ``"missing"``.
    """
    rows = []
    for run, record in zip(runs, records):
        record = record or {"status": "missing"}
        row = {"run": run.id, "status": record["status"]}
        row.update({key: _cell(value) for key, value in run.columns.items()})
        row.update(record.get("row") or {})
        wall = record.get("wall_s")
        row.update({"wall_s": None if wall is None else round(wall, 6), "attempts": record.get("attempts", 0),
                    "error": record.get("error"), "state_file": record.get("state_file")})
        row.update({k: v for k, v in flatten(run.params).items() if k not in row})
        rows.append(row)
    columns = list(dict.fromkeys(key for row in rows for key in row))
    return [{key: row.get(key) for key in columns} for row in rows]


def _column_values(values: list) -> list:
    """One type per column for Parquet: ints and floats together become floats, mixed with text all text; control
    characters in text escaped (`labrig.validate.printable`), as in the CSV."""
    kinds = {type(v) for v in values if v is not None}
    if kinds == {int, float}:
        return [None if v is None else float(v) for v in values]
    if len(kinds) > 1 or kinds == {str}:
        return [None if v is None else printable(v) for v in values]
    return values


def write_table(rows: Sequence[dict], out: str | os.PathLike, name: str = "table") -> tuple[Path, Path | None]:
    """Write ``out/<name>.csv`` (and ``<name>.parquet`` when pyarrow is importable), atomically.

    Returns the two paths (None for Parquet without pyarrow).
    """
    out = Path(out)
    csv_path = write_csv(out / f"{name}.csv", list(rows))
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        return csv_path, None
    columns = {printable(key): _column_values([row[key] for row in rows]) for key in rows[0]}
    parquet_path = out / f"{name}.parquet"
    with atomic_path(parquet_path) as tmp:
        pq.write_table(pa.table(columns), tmp)
    return csv_path, parquet_path


def parse_cell(text: str):
    """A CSV cell as Python: "" -> None, then int, float, bool, else the text."""
    if text == "":
        return None
    if text in ("True", "False"):
        return text == "True"
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def read_table(path: str | os.PathLike) -> list[dict]:
    """The rows of a sweep table (.csv or .parquet) as dicts; missing values are None.

    Raises
    ------
    FileNotFoundError, ValueError
        If the file does not exist, or is not a readable table.
    """
    path = existing_file(path, "table")
    if path.suffix == ".parquet":
        try:
            import pyarrow.parquet as pq
        except ImportError:
            raise InputError("reading Parquet needs pyarrow (pip install 'nanodisorder[sweep]'); read the .csv") from None
        try:
            return pq.read_table(path).to_pylist()
        except Exception as exc:  # pyarrow raises its own error types
            raise InputError(f"{path}: not a readable Parquet table ({exc})") from None
    if path.stat().st_size > MAX_TABLE_BYTES:
        raise InputError(f"{path}: the table has {path.stat().st_size:,} bytes, more than the {MAX_TABLE_BYTES:,} read")
    try:
        with open(path, newline="", encoding="utf-8") as stream:
            reader = csv.DictReader(stream)
            rows = []
            for row in reader:
                if None in row or None in row.values():  # more or fewer cells than the header has columns
                    raise InputError(f"{path}: line {reader.line_num} has {len(row) - (None in row) + len(row.get(None, []))} "
                                     f"cells, the header {len(reader.fieldnames or ())} (a truncated or edited table?)")
                rows.append({key: parse_cell(value) for key, value in row.items()})
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise InputError(f"{path}: not a readable CSV table ({exc})") from None
    if not rows:
        raise InputError(f"{path}: the table has no rows")
    return rows


def is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
