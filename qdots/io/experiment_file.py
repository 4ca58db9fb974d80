"""TOML experiment files for an `Experiment`.

An experiment file holds one experiment: top-level ``name``, ``seed`` and
``grating``, the tables ``[board]``, ``[deposition]``, ``[restitution]`` and
``[engine]``, and one ``[[forces]]`` table per force. Every key is optional
(a missing key takes its default) and `experiment_to_toml` writes all of
them, with units and allowed ranges in comments. Floats are written with
``repr`` and read back exactly, so ``load_experiment(save_experiment(exp))
== exp``. Unknown keys, wrong types and out-of-range values raise a
ValueError naming the file and the full key (e.g. ``deposition.sigmaa``).

Files written by 0.1 keep loading with the same meaning: their spellings
(``deposition.protocol = "center"``, a ``"CenterGravity"`` force with its
``center`` key) are read as today's (`qdots.io.old_spellings`), without a
warning. The Python API takes today's spellings only.
"""

from __future__ import annotations

import dataclasses
import inspect
import os
from pathlib import Path

from labrig.files import write_text_atomic
from labrig.tomlfile import as_table, check_keys, from_source, parse_toml, read_toml, toml_line, top_level
from labrig.validate import MAX_SEED, InputError, number, typed

from ..restitution import MAX_STICKING_SPEED, Restitution
from ..experiment import MAX_SETTLE, Board, Deposition, Experiment
from ..forces import FORCE_TYPES
from ..forces.fields import MAX_ACCELERATION, MAX_DRAG
from ..forces.thermal import MAX_GAMMA, MAX_KICKS_PER_RUN, MAX_KICKS_PER_STEP, MAX_KT, MAX_SCALE
from ..forces.thermal import MAX_INTERVAL as MAX_KICK_INTERVAL
from ..forces.vdw import MAX_RANGE, MAX_STRENGTH
from ..neighbours import MAX_SKIN
from ..placement import MAX_TRIES
from ..protocols import MAX_INTERVAL
from ..scene import MAX_DOTS, MAX_LENGTH, MAX_MASS
from ..engine.settings import (DT_RANGE, MAX_FAR_INTERVAL, MAX_HASH_CELLS, MAX_ITERATIONS, MAX_NEAR_GAP, MAX_SLOP,
                               MAX_SUBSTEPS, TOLERANCE_RANGE, EngineSettings)
from ..simulation import MAX_STEPS
from .old_spellings import current_experiment

_PX = f"(0, {number(MAX_LENGTH)}]"

#: Top-level scalars: key -> (kind, comment).
TOP = {
    "name": ("str", "label of the run"),
    "seed": ("int", f"integer in [0, {MAX_SEED}]; root of the simulation and deposition random streams"),
    "grating": ("float", "px, a wall at y = grating keeps the dots in 0 < y < grating; "
                         "in (mean_diameter, board.height), 0 = no grating"),
}
#: Tables: name -> (class, {key: (kind, comment)}). Kinds ending in "?" may be unset (None).
TABLES = {
    "board": (Board, {
        "width": ("float", f"px, in {_PX}"),
        "height": ("float", f"px, in {_PX}"),
        "closed": ("bool", "the four edges are hard walls"),
    }),
    "deposition": (Deposition, {
        "protocol": ("str", '"random" (uniform in the board or grating channel) | "centre" (ring around the centre)'),
        "n_dots": ("int", f"dots deposited, integer in [0, {MAX_DOTS:,}]"),
        "mean_diameter": ("float", f"px, in {_PX}"),
        "sigma": ("float", "fraction of mean diameter, [0, 1)"),
        "mass_model": ("str", '"equal" | "area" (d/mean)^2 | "volume" (d/mean)^3 | "bimodal"'),
        "heavy_mass": ("float", f"mass of the heavy half of a bimodal board, mean-dot masses, in (0, {number(MAX_MASS)}]"),
        "interval": ("float", f"s of simulated time between two dots, in [0, {number(MAX_INTERVAL)}]"),
        "settle": ("float", f"s of simulated time after the last dot, in [0, {number(MAX_SETTLE)}]; "
                            f"the whole run at most {MAX_STEPS:,} steps"),
        "max_tries": ("int", f"rejected candidates in a row before the board counts as full, in [1, {MAX_TRIES:,}]"),
    }),
    "restitution": (Restitution, {
        "mean": ("float", "mean dot-dot coefficient of restitution, [0, 1]"),
        "wall": ("float", "dot-wall coefficient of restitution, [0, 1]"),
        "sticking_speed": ("float", f"px/s, slower dot-dot impacts are perfectly inelastic, in [0, "
                                    f"{number(MAX_STICKING_SPEED)}]"),
    }),
    "engine": (EngineSettings, {
        "dt": ("float", f"s, time step, in [{number(DT_RANGE[0])}, {number(DT_RANGE[1])}]"),
        "substeps": ("int", f"fewest Chipmunk steps per time step, in [1, {MAX_SUBSTEPS}]"),
        "overlap_tolerance": ("float?", f"radii a dot may travel into a contact in one Chipmunk step, in "
                                        f"[{number(TOLERANCE_RANGE[0])}, {number(TOLERANCE_RANGE[1])}]; false: "
                                        "always `substeps`"),
        "max_substeps": ("int", f"most Chipmunk steps per time step for overlap_tolerance, in [1, {MAX_SUBSTEPS}]"),
        "iterations": ("int", f"solver iterations per sub-step, in [1, {MAX_ITERATIONS}]"),
        "collision_slop": ("float", f"px of overlap left uncorrected, in [0, {number(MAX_SLOP)}]"),
        "collision_bias": ("float?", "overlap fraction left after 1 s, [0, 1); unset: 30 % corrected per sub-step"),
        "spatial_hash": ("pair?", f"[cell size px > 0, count in [1, {MAX_HASH_CELLS:,}]]; unset: Chipmunk's "
                                  "bounding-box tree"),
        "threads": ("int", "solver threads, 1 or 2"),
        "pair_skin": ("float", f"px, Verlet skin of the van der Waals pair list, in [0, {number(MAX_SKIN)}]"),
        "near_gap": ("float", f"px, van der Waals pairs closer than this are pulled every step, in "
                              f"(0, {number(MAX_NEAR_GAP)}]"),
        "far_interval": ("float?", f"s between passes over the farther van der Waals pairs, in "
                                   f"(0, {number(MAX_FAR_INTERVAL)}]; false: every pair every step"),
        "tune_allocator": ("bool", "raise glibc's allocator thresholds (speed only)"),
    }),
}
#: Comments for force parameters: type -> {parameter: comment}.
FORCE_NOTES = {
    "VanDerWaals": {"model": '"thesis" (Java proxy) | "hamaker" (Eq 2.2)',
                    "r0": f"px, range R0 of the proxy, in (0, {number(MAX_RANGE)}]",
                    "strength": f"Hamaker constant, mean-dot mass px^2/s^2, in [0, {number(MAX_STRENGTH)}]",
                    "min_gap": "px, closer counts as contact", "max_gap": "px, no force beyond",
                    "contact": '"hold" | "zero" (force below min_gap)',
                    "offset": "px, the proxy's b, below min_gap; unset: from restitution.sticking_speed"},
    "ThermalKicks": {"interval": f"s between kicks, in (0, {number(MAX_KICK_INTERVAL)}]; at most "
                                 f"{MAX_KICKS_PER_STEP:,} kicks per engine.dt and {MAX_KICKS_PER_RUN:,} per run",
                     "scale": f"multiple of the thesis kick speed, in [0, {number(MAX_SCALE)}]"},
    "Langevin": {"gamma": f"1/s, friction rate, in [0, {number(MAX_GAMMA)}]",
                 "kT": f"mean-dot mass px^2/s^2, in [0, {number(MAX_KT)}]"},
    "Drag": {"linear": f"f1, 1/s, in [0, {number(MAX_DRAG)}]", "quadratic": f"f2, 1/px, in [0, {number(MAX_DRAG)}]"},
    "Gravity": {"acceleration": f"[ax, ay], px/s^2, each within +-{number(MAX_ACCELERATION)}"},
    "CentreGravity": {"centre": "[x, y], px", "magnitude": f"px/s^2, in [0, {number(MAX_ACCELERATION)}]"},
}


def experiment_to_toml(exp: Experiment) -> str:
    """The experiment file text of ``exp``: every parameter, with units and ranges in comments."""
    lines = ["# qdots experiment. Units: px, s (simulated), masses in units of a mean-size dot's mass.",
             "# Every key is optional; a missing key takes the default. Load with qdots.io.experiment_file.load_experiment.",
             ""]
    lines += [toml_line(key, getattr(exp, key), note) for key, (_, note) in TOP.items()]
    if not exp.forces:
        lines.append("forces = []  # no forces")
    for table, (_, schema) in TABLES.items():
        obj = getattr(exp, table)
        defaults = {f.name: f.default for f in dataclasses.fields(obj)} if dataclasses.is_dataclass(obj) else {}
        lines += ["", f"[{table}]"] + [toml_line(key, getattr(obj, key), note, defaults.get(key))
                                       for key, (_, note) in schema.items()]
    for spec in exp.forces:
        notes = FORCE_NOTES.get(spec["type"], {})
        defaults = force_defaults(spec["type"])
        lines += ["", "[[forces]]"] + [toml_line(k, v, notes.get(k), defaults.get(k)) for k, v in spec.items()]
    return "\n".join(lines) + "\n"


def force_defaults(name: str) -> dict:
    """The constructor defaults of the force type ``name`` ({} for an unknown type)."""
    cls = FORCE_TYPES.get(name)
    if cls is None:
        return {}
    return {key: p.default for key, p in inspect.signature(cls.__init__).parameters.items()
            if p.default is not inspect.Parameter.empty}


def _force_table(spec: dict) -> dict:
    """A ``[[forces]]`` table as constructor arguments: ``false`` unsets (None) a parameter whose default is set
    (the way `experiment_to_toml` writes such a parameter; no force takes a true/false parameter)."""
    defaults = force_defaults(spec.get("type"))
    return {key: None if value is False and defaults.get(key) is not None else value for key, value in spec.items()}


def save_experiment(exp: Experiment, path: str | os.PathLike) -> Path:
    """Write ``exp`` to ``path`` as TOML, atomically (whole or not at all); return the path."""
    if not isinstance(exp, Experiment):
        raise TypeError(f"exp must be a qdots.experiment.Experiment, got {type(exp).__name__}")
    return write_text_atomic(path, experiment_to_toml(exp))


def _table(name: str, data) -> object:
    cls, schema = TABLES[name]
    check_keys(name, as_table(name, data), schema)
    values = {key: typed(f"{name}.{key}", value, schema[key][0]) for key, value in data.items()}
    try:
        return cls(**values)
    except ValueError as exc:
        msg = str(exc)
        if msg.lower().startswith(f"{name}."):
            raise InputError(name + msg[len(name):]) from None
        raise InputError(f"{name}.{msg}") from None


def experiment_from_dict(data: dict) -> Experiment:
    """An `Experiment` from parsed TOML (nested dicts); missing keys take their defaults, and the
    spellings of files written by 0.1 are read as today's (`qdots.io.old_spellings`).

    Raises
    ------
    ValueError
        Naming the full key of an unknown key, a wrong type or an out-of-range value.
    """
    data = current_experiment(data)
    kwargs = top_level(data, TOP, [*TABLES, "forces"])
    kwargs.update({name: _table(name, data[name]) for name in TABLES if name in data})
    if "forces" in data:
        forces = data["forces"]
        if not isinstance(forces, list) or not all(isinstance(f, dict) for f in forces):
            raise InputError(f"forces must be an array of tables ([[forces]]), got {forces!r}")
        kwargs["forces"] = tuple(_force_table(f) for f in forces)
    return Experiment(**kwargs)


def experiment_from_toml(text: str, source: str = "<string>") -> Experiment:
    """Parse scene-file text; errors are ValueErrors starting with ``source``."""
    return from_source(experiment_from_dict, parse_toml(text, source), source)


def load_experiment(path: str | os.PathLike) -> Experiment:
    """Read an experiment file; `InputError` (a ValueError) starting with the path if it cannot be read or
    decoded (UTF-8), is not valid TOML or holds a bad key or value, `FileNotFoundError` if it is missing."""
    return from_source(experiment_from_dict, read_toml(path, "experiment file"), str(path))
