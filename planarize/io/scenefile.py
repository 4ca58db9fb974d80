"""TOML scene files for planarize: a `planarize.scene.PlanarizeScene` as a file.

A scene file holds top-level ``name`` and ``seed``, a ``[surface]`` table (``kind`` and that kind's parameters), a
``[run]`` table (the thickness, the model, the records: `planarize.scene.RunSettings`) and an ``[engine]`` table
(``kind`` and that engine's settings, declared by its settings class: ``rtol`` for ``"continuum"``, ``tolerance``
and ``interacting`` for ``"fast"``); every key is declared in `planarize.scene` and `planarize.engines`. Files
written before 0.3 held the engine's name and settings in ``[run]`` (``engine``, ``rtol``, ``tolerance``,
``interacting``): they are read, into ``[engine]``, with a `FutureWarning` that says so. Every key but ``surface.path`` of
a ``"file"`` surface is optional: a missing key takes its default. `scene_to_toml` writes every key with units and
allowed ranges in comments; floats are written with ``repr`` and read back exactly, so ``load_scene(save_scene(s))
== s``. Unknown keys, wrong types and out-of-range values raise a `labrig.validate.InputError` naming the file and
the full key (e.g. ``run.step``); the TOML reading, writing and key checks are `labrig.tomlfile`'s. A relative
``surface.path`` is relative to the scene file's directory.
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path

from labrig.files import write_text_atomic
from labrig.params import file_schema
from labrig.tomlfile import as_table, check_keys, from_source, parse_toml, read_toml, toml_line, top_level
from labrig.validate import InputError, typed

from ..engines import KIND, engine_from_dict
from ..scene import OLD_RUN_KEYS, RUN, SURFACES, TOP, PlanarizeScene, RunSettings, SurfaceSpec

# -- TOML --------------------------------------------------------------------------------------

def scene_to_toml(scene: PlanarizeScene) -> str:
    """The scene file text: every key, with units and ranges in comments."""
    kind = scene.surface.kind
    lines = ["# planarize scene. Lengths in nm unless a unit is given. Every key is optional",
             "# (surface.path is required for kind = \"file\"). Load with planarize.io.scenefile.load_scene.", ""]
    lines += [toml_line(key, getattr(scene, key), note) for key, (_, note) in TOP.items()]
    lines += ["", "[surface]", toml_line("kind", kind, " | ".join(f'"{k}"' for k in SURFACES))]
    schema = SURFACES[kind][1]
    lines += [toml_line(key, scene.surface.params.get(key), note) for key, (_, note) in schema.items()]
    lines += ["", "[run]"] + [toml_line(key, getattr(scene.run, key), note) for key, (_, note) in RUN.items()]
    engine = scene.engine
    lines += ["", "[engine]", toml_line("kind", engine.name, KIND.comment())]
    lines += [toml_line(key, getattr(engine, key), note) for key, (_, note) in file_schema(type(engine).PARAMS).items()]
    return "\n".join(lines) + "\n"


def save_scene(scene: PlanarizeScene, path: str | os.PathLike) -> Path:
    """Write ``scene`` to ``path`` as TOML, atomically; returns the path."""
    if not isinstance(scene, PlanarizeScene):
        raise TypeError(f"scene must be a PlanarizeScene, got {type(scene).__name__}")
    return write_text_atomic(path, scene_to_toml(scene))


def scene_from_dict(data: dict, base_dir: str | os.PathLike | None = None) -> PlanarizeScene:
    """A scene from parsed TOML; a relative ``surface.path`` is taken relative to ``base_dir``.

    Raises
    ------
    ValueError
        Naming the full key of an unknown key, a wrong type or an out-of-range value.
    """
    top = top_level(data, TOP, ["surface", "run", "engine"])
    surface = as_table("surface", data.get("surface", {}))
    run = dict(as_table("run", data.get("run", {})))
    engine = dict(as_table("engine", data.get("engine", {})))
    old = [key for key in OLD_RUN_KEYS if key in run]
    if old:
        if "engine" in data:
            raise InputError(f"run.{old[0]}: the engine and its settings are the [engine] table's: write it as "
                             f"engine.{OLD_RUN_KEYS[old[0]]}")
        engine = {OLD_RUN_KEYS[key]: run.pop(key) for key in old}
        warnings.warn(f"{', '.join('run.' + key for key in old)}: since 0.3 the engine and its settings are an "
                      f"[engine] table (kind = the engine); this file is read as such (save the scene again to write it "
                      f"so)", FutureWarning, stacklevel=2)
    params = {k: v for k, v in surface.items() if k != "kind"}
    kind = typed("surface.kind", surface.get("kind", "hill"), "str")
    if kind not in SURFACES:
        raise InputError(f"surface.kind must be one of {', '.join(map(repr, SURFACES))}, got {kind!r}")
    if kind == "file" and isinstance(params.get("path"), str) and base_dir is not None:
        params["path"] = str(Path(base_dir, params["path"]))
    check_keys("run", run, list(RUN))
    try:
        run_settings = RunSettings(**run)
    except ValueError as exc:
        raise InputError(f"run.{exc}") from None
    where = "run" if old else "engine"  # an old file's keys named as it wrote them
    try:
        settings = engine_from_dict(engine, where)
    except InputError as exc:
        raise InputError(str(exc).replace(f"{where}.kind", f"{where}.engine") if old else str(exc)) from None
    return PlanarizeScene(**top, surface=SurfaceSpec(kind, params), run=run_settings, engine=settings)


def scene_from_toml(text: str, source: str = "<string>", base_dir=None) -> PlanarizeScene:
    """Parse scene-file text; errors are ValueErrors starting with ``source``."""
    return from_source(scene_from_dict, parse_toml(text, source), source, base_dir)


def load_scene(path: str | os.PathLike) -> PlanarizeScene:
    """Read a scene file (a relative ``surface.path`` is relative to its directory).

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        If it cannot be read, is not valid TOML or holds a bad key or value;
        the message starts with the path.
    """
    path = Path(path)
    return from_source(scene_from_dict, read_toml(path, "scene file"), str(path), path.parent)


__all__ = ["load_scene", "save_scene", "scene_from_toml", "scene_to_toml", "scene_from_dict"]
