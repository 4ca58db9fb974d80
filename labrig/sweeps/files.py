"""Sweep files (TOML): what to sweep, read and checked with errors naming the file and the key.

A sweep file::

    base = "scene.toml"             # a parameter file, relative to this file; or an inline [base] table
    seeds = 4                       # a count (from the base's seed) or a list, e.g. [154, 155]

    [axes]                          # cartesian product; a list, or a range {start, stop, num | step}
    "deposition.sigma" = [0.0, 0.05, 0.10, 0.15]
    "deposition.n_dots" = {start = 100, stop = 300, step = 100}

    [[points]]                      # optional explicit points, each times the axes
    label = "free"
    [[points]]
    label = "grating"
    grating = 77.94
    deposition.n_dots = 150

    [output]
    dir = "fig2-4"                  # relative to this file (default: the file's name without .toml)
    state = true                    # also keep each run's final state (default false)

Quoted (``"deposition.sigma" = ...``) and bare dotted keys (``deposition.sigma = ...``,
which TOML reads as nested tables) mean the same.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from ..tomlfile import read_toml
from ..validate import InputError
from .spec import RANGE_KEYS, Sweep

#: Top-level keys of a sweep file.
FILE_KEYS = ("base", "axes", "points", "seeds", "output")
#: Keys of its [output] table.
OUTPUT_KEYS = ("dir", "state")


@dataclass(frozen=True)
class SweepFile:
    """A parsed sweep file: the sweep, where its results go, and whether runs keep their final state."""

    sweep: Sweep
    out: Path
    state: bool = False
    source: str = "<sweep>"


def _dotted(tree: dict, prefix: str = "", keep=lambda value: False) -> dict:
    """Nested tables as dotted keys; a value for which ``keep`` is true stays whole."""
    flat = {}
    for key, value in tree.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict) and not keep(value):
            flat.update(_dotted(value, f"{name}.", keep))
        else:
            flat[name] = value
    return flat


def _is_range(value: dict) -> bool:
    return any(key in value for key in RANGE_KEYS)


def _read_base(name: str, base_dir: Path) -> dict:
    return read_toml(base_dir / name, "base file")


def sweep_from_dict(data: dict, *, base_dir: str | os.PathLike = ".", seed_key: str = "seed",
                    default_out: str = "sweep", read_base: Callable[[str, Path], dict] = _read_base) -> SweepFile:
    """A `SweepFile` from parsed TOML; relative paths (``base``, ``output.dir``) start at ``base_dir``.

    ``read_base(name, base_dir)`` turns ``base = "name"`` into parameters
    (default: read the TOML file ``base_dir / name`` as it is).
    """
    base_dir = Path(base_dir)
    if not isinstance(data, dict):
        raise InputError(f"a sweep must be a table, got {type(data).__name__}")
    extra = [k for k in data if k not in FILE_KEYS]
    if extra:
        raise InputError(f"unknown key {extra[0]!r} (allowed: {', '.join(FILE_KEYS)})")
    if "base" not in data:
        raise InputError('missing key "base": a parameter file (base = "scene.toml") or a [base] table')
    base = data["base"]
    if isinstance(base, str):
        base = read_base(base, base_dir)
    elif not isinstance(base, dict):
        raise InputError(f"base must be a file name or a table, got {base!r}")
    axes = data.get("axes", {})
    if not isinstance(axes, dict):
        raise InputError(f"axes must be a table ([axes]), got {axes!r}")
    points = data.get("points", [{}])
    if not isinstance(points, list) or not all(isinstance(p, dict) for p in points):
        raise InputError(f"points must be an array of tables ([[points]]), got {points!r}")
    output = data.get("output", {})
    if not isinstance(output, dict):
        raise InputError(f"output must be a table ([output]), got {output!r}")
    extra = [k for k in output if k not in OUTPUT_KEYS]
    if extra:
        raise InputError(f"unknown key 'output.{extra[0]}' (allowed in [output]: {', '.join(OUTPUT_KEYS)})")
    out = output.get("dir", default_out)
    if not (isinstance(out, str) and out.strip()):
        raise InputError(f"output.dir must be a directory name, got {out!r}")
    state = output.get("state", False)
    if not isinstance(state, bool):
        raise InputError(f"output.state must be true or false, got {state!r}")
    sweep = Sweep(base=base, axes=_dotted(axes, keep=_is_range), points=tuple(_dotted(p) for p in points),
                  seeds=data.get("seeds"), seed_key=seed_key)
    return SweepFile(sweep, base_dir / out, state)


def load_sweep_file(path: str | os.PathLike, *, seed_key: str = "seed",
                    read_base: Callable[[str, Path], dict] = _read_base) -> SweepFile:
    """Read and check a sweep file; errors are ValueErrors starting with its path.

    The runs themselves are checked by `Sweep.runs` with the runner's
    ``canonical`` function (unknown parameter keys, bad values).
    """
    path = Path(path)
    data = read_toml(path, "sweep file")
    try:
        parsed = sweep_from_dict(data, base_dir=path.parent, seed_key=seed_key, default_out=path.stem,
                                 read_base=read_base)
    except ValueError as exc:
        raise InputError(f"{path}: {exc}") from None
    return SweepFile(parsed.sweep, parsed.out, parsed.state, str(path))


def run_loaded(sweep_file: SweepFile, runner, out=None, **options):
    """Run a parsed sweep file with ``runner`` (`labrig.sweeps.run_sweep` options); ``out`` overrides its output."""
    from .execute import run_sweep

    return run_sweep(sweep_file.sweep, runner, sweep_file.out if out is None else out, state=sweep_file.state,
                     **options)
