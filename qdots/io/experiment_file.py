"""TOML scene files for an `Experiment`.

A scene file holds one experiment: top-level ``name``, ``seed`` and
``grating``, the tables ``[board]``, ``[deposition]``, ``[restitution]`` and
``[engine]``, and one ``[[forces]]`` table per force. Every key is optional
(a missing key takes its default) and `experiment_to_toml` writes all of
them, with units and allowed ranges in comments. Floats are written with
``repr`` and read back exactly, so ``load_experiment(save_experiment(exp))
== exp``. Unknown keys, wrong types and out-of-range values raise a
ValueError naming the file and the full key (e.g. ``deposition.sigmaa``).
"""

from __future__ import annotations

import os
from pathlib import Path

from labrig.files import write_text_atomic
from labrig.tomlfile import check_keys, from_source, parse_toml, read_toml, toml_line
from labrig.validate import InputError, typed

from ..collisions import Restitution
from ..experiment import Board, Deposition, Experiment
from ..simulation import EngineSettings

#: Top-level scalars: key -> (kind, comment).
TOP = {
    "name": ("str", "label of the run"),
    "seed": ("int", "integer >= 0; root of the simulation and deposition random streams"),
    "grating": ("float", "px, a wall at y = grating keeps the dots in 0 < y < grating; "
                         "in (mean_diameter, board.height), 0 = no grating"),
}
#: Tables: name -> (class, {key: (kind, comment)}). Kinds ending in "?" may be unset (None).
TABLES = {
    "board": (Board, {
        "width": ("float", "px, > 0"),
        "height": ("float", "px, > 0"),
        "closed": ("bool", "the four edges are hard walls"),
    }),
    "deposition": (Deposition, {
        "protocol": ("str", '"random" (uniform in the board or grating channel) | "center" (ring around the centre)'),
        "n_dots": ("int", "dots deposited, integer >= 0"),
        "mean_diameter": ("float", "px, > 0"),
        "sigma": ("float", "fraction of mean diameter, [0, 1)"),
        "mass_model": ("str", '"equal" | "area" (d/mean)^2 | "volume" (d/mean)^3 | "bimodal"'),
        "heavy_mass": ("float", "mass of the heavy half of a bimodal board, mean-dot masses, > 0"),
        "interval": ("float", "s of simulated time between two dots, >= 0"),
        "settle": ("float", "s of simulated time after the last dot, >= 0"),
        "max_tries": ("int", "rejected candidates in a row before the board counts as full, integer >= 1"),
    }),
    "restitution": (Restitution, {
        "mean": ("float", "mean dot-dot coefficient of restitution, [0, 1]"),
        "wall": ("float", "dot-wall coefficient of restitution, [0, 1]"),
        "sticking_speed": ("float", "px/s, slower dot-dot impacts are perfectly inelastic, >= 0"),
    }),
    "engine": (EngineSettings, {
        "dt": ("float", "s, time step, > 0"),
        "substeps": ("int", "Chipmunk steps per time step, integer >= 1"),
        "iterations": ("int", "solver iterations per sub-step, integer >= 1"),
        "collision_slop": ("float", "px of overlap left uncorrected, >= 0"),
        "collision_bias": ("float?", "overlap fraction left after 1 s, [0, 1); unset: 30 % corrected per sub-step"),
        "spatial_hash": ("pair?", "[cell size px > 0, count >= 1]; unset: Chipmunk's bounding-box tree"),
        "threads": ("int", "solver threads, 1 or 2"),
    }),
}
#: Comments for force parameters: type -> {parameter: comment}.
FORCE_NOTES = {
    "VanDerWaals": {"model": '"thesis" (Java proxy) | "hamaker" (Eq 2.2)', "r0": "px, range R0 of the proxy",
                    "strength": "Hamaker constant, mean-dot mass px^2/s^2", "min_gap": "px, closer counts as contact",
                    "max_gap": "px, no force beyond", "contact": '"hold" | "zero" (force below min_gap)',
                    "sticking_speed": "px/s, enters the proxy offset b", "skin": "px, Verlet skin of the pair list"},
    "ThermalKicks": {"interval": "s between kicks", "scale": "multiple of the thesis kick speed"},
    "Langevin": {"gamma": "1/s, friction rate", "kT": "mean-dot mass px^2/s^2"},
    "Drag": {"linear": "f1, 1/s", "quadratic": "f2, 1/px"},
    "Gravity": {"acceleration": "[ax, ay], px/s^2"},
    "CenterGravity": {"center": "[x, y], px", "magnitude": "px/s^2, >= 0"},
}


def experiment_to_toml(exp: Experiment) -> str:
    """The scene file text of ``exp``: every parameter, with units and ranges in comments."""
    lines = ["# qdots experiment. Units: px, s (simulated), masses in units of a mean-size dot's mass.",
             "# Every key is optional; a missing key takes the default. Load with qdots.io.experiment_file.load_experiment.",
             ""]
    lines += [toml_line(key, getattr(exp, key), note) for key, (_, note) in TOP.items()]
    if not exp.forces:
        lines.append("forces = []  # no forces")
    for table, (_, schema) in TABLES.items():
        obj = getattr(exp, table)
        lines += ["", f"[{table}]"] + [toml_line(key, getattr(obj, key), note) for key, (_, note) in schema.items()]
    for spec in exp.forces:
        notes = FORCE_NOTES.get(spec["type"], {})
        lines += ["", "[[forces]]"] + [toml_line(k, v, notes.get(k)) for k, v in spec.items()]
    return "\n".join(lines) + "\n"


def save_experiment(exp: Experiment, path: str | os.PathLike) -> Path:
    """Write ``exp`` to ``path`` as TOML, atomically (whole or not at all); return the path."""
    if not isinstance(exp, Experiment):
        raise TypeError(f"exp must be a qdots.experiment.Experiment, got {type(exp).__name__}")
    return write_text_atomic(path, experiment_to_toml(exp))


def _table(name: str, data) -> object:
    cls, schema = TABLES[name]
    if not isinstance(data, dict):
        raise InputError(f"{name} must be a table ([{name}]), got {data!r}")
    check_keys(name, data, schema)
    values = {key: typed(f"{name}.{key}", value, schema[key][0]) for key, value in data.items()}
    try:
        return cls(**values)
    except ValueError as exc:
        msg = str(exc)
        if msg.lower().startswith(f"{name}."):
            raise InputError(name + msg[len(name):]) from None
        raise InputError(f"{name}.{msg}") from None


def experiment_from_dict(data: dict) -> Experiment:
    """An `Experiment` from parsed TOML (nested dicts); missing keys take their defaults.

    Raises
    ------
    ValueError
        Naming the full key of an unknown key, a wrong type or an out-of-range value.
    """
    if not isinstance(data, dict):
        raise InputError(f"a scene must be a table, got {type(data).__name__}")
    check_keys("", data, [*TOP, *TABLES, "forces"])
    kwargs = {key: typed(key, data[key], kind) for key, (kind, _) in TOP.items() if key in data}
    kwargs.update({name: _table(name, data[name]) for name in TABLES if name in data})
    if "forces" in data:
        forces = data["forces"]
        if not isinstance(forces, list) or not all(isinstance(f, dict) for f in forces):
            raise InputError(f"forces must be an array of tables ([[forces]]), got {forces!r}")
        kwargs["forces"] = tuple(forces)
    return Experiment(**kwargs)


def experiment_from_toml(text: str, source: str = "<string>") -> Experiment:
    """Parse scene-file text; errors are ValueErrors starting with ``source``."""
    return from_source(experiment_from_dict, parse_toml(text, source), source)


def load_experiment(path: str | os.PathLike) -> Experiment:
    """Read a scene file.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        If it cannot be read or decoded (UTF-8), is not valid TOML, or holds
        a bad key or value; the message starts with the path.
    """
    return from_source(experiment_from_dict, read_toml(path, "scene file"), str(path))
