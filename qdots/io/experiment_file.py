"""TOML experiment files for an `Experiment`.

An experiment file holds one experiment: top-level ``name``, ``seed`` and
``grating``, the tables ``[board]``, ``[deposition]``, ``[restitution]`` and
``[engine]``, and one ``[[forces]]`` table per force. Every key is optional
(a missing key takes its default) and `experiment_to_toml` writes all of
them, with units and allowed ranges in comments generated from each
parameter's declaration (`labrig.params.Param`), the one the classes check
values with. Floats are written with
``repr`` and read back exactly, so ``load_experiment(save_experiment(exp))
== exp``. Unknown keys, wrong types and out-of-range values raise a
ValueError naming the file and the full key (e.g. ``deposition.sigmaa``).

The ``[engine]`` table's ``kind`` says which engine runs (`qdots.engine.ENGINES`)
and its other keys are that engine's settings; keys of another engine are
checked and left unread, so that one key switches the engine (files of 0.2
held both engines' settings). Files written by 0.1 and 0.2 keep loading with
the same meaning: their spellings (``deposition.protocol = "center"``, a
``"CenterGravity"`` force with its ``center`` key, the van der Waals pair
list's knobs in its force table) are read as today's
(`qdots.io.old_spellings`), without a warning. The Python API takes today's
spellings only.
"""

from __future__ import annotations

import dataclasses
import inspect
import os
from pathlib import Path

from labrig.files import write_text_atomic
from labrig.params import file_schema
from labrig.tomlfile import as_table, check_keys, from_source, parse_toml, read_toml, toml_line, top_level
from labrig.validate import InputError, typed

from ..engine import Settings, engine_class, engine_params
from ..experiment import Board, Deposition, Experiment
from ..forces import FORCE_TYPE, FORCE_TYPES
from ..restitution import Restitution
from .old_spellings import current_experiment

#: The tables of an experiment file and the classes they build. The keys of a table, their kinds, ranges and
#: units, and the comments a saved file gives them are the class's declarations (``cls.PARAMS``,
#: `labrig.params.Param`; for ``[engine]``, `qdots.engine.engine_params`: its ``kind`` and that engine's
#: settings class), as are the top-level keys (`Experiment.PARAMS`) and each force's parameters
#: (``FORCE_TYPES[type].PARAMS``).
TABLES: dict[str, type[Board | Deposition | Restitution | Settings]] = {
    "board": Board, "deposition": Deposition, "restitution": Restitution, "engine": Settings}


def table_params(obj) -> dict:
    """The declarations of the table that holds ``obj`` (one of an experiment's `TABLES`), in file order."""
    return engine_params(obj) if isinstance(obj, Settings) else type(obj).PARAMS


def experiment_to_toml(exp: Experiment) -> str:
    """The experiment file text of ``exp``: every parameter, its unit and range in a comment (from its declaration)."""
    lines = ["# qdots experiment. Units: px, s (simulated), masses in units of a mean-size dot's mass.",
             "# Every key is optional; a missing key takes the default, `key = false` unsets a key whose default",
             ("# is set. Comments: what a key is, its unit and its range. Load with "
              "qdots.io.experiment_file.load_experiment."),
             ""]
    lines += [toml_line(key, getattr(exp, key), param.comment()) for key, param in Experiment.PARAMS.items()]
    if not exp.forces:
        lines.append("forces = []  # no forces")
    for table in TABLES:
        obj = getattr(exp, table)
        defaults = {f.name: f.default for f in dataclasses.fields(obj)}
        lines += ["", f"[{table}]"] + [toml_line(key, getattr(obj, key), param.comment(), defaults.get(key))
                                       for key, param in table_params(obj).items()]
    for spec in exp.forces:
        declared = FORCE_TYPES[spec["type"]].PARAMS
        defaults = force_defaults(spec["type"])
        lines += ["", "[[forces]]", toml_line("type", spec["type"], FORCE_TYPE.comment())]
        lines += [toml_line(k, v, declared[k].comment(), defaults.get(k)) for k, v in spec.items() if k != "type"]
    return "\n".join(lines) + "\n"


def force_defaults(name: object) -> dict:
    """The constructor defaults of the force type ``name`` ({} for an unknown type, or a type that is not a
    string: the force reader refuses it in words)."""
    cls = FORCE_TYPES.get(name) if isinstance(name, str) else None
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
    cls = TABLES[name]
    params = cls.PARAMS
    if name == "engine":
        cls = engine_class(typed("engine.kind", as_table(name, data).get("kind", "chipmunk"), "str"))
        params = engine_params(cls())
    check_keys(name, as_table(name, data), params)
    values = {key: typed(f"{name}.{key}", value, params[key].file_kind) for key, value in data.items() if key != "kind"}
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
    kwargs = top_level(data, file_schema(Experiment.PARAMS), [*TABLES, "forces"])
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
