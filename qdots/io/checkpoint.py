"""Saving and resuming boards: one ``.npz`` file per checkpoint.

Format (``format = "qdots-state"``, ``version = 1``): a NumPy ``.npz`` archive
(uncompressed zip) with the arrays

* ``positions`` (N, 2) px, ``velocities`` (N, 2) px/s,
* ``radii`` (N,) px, ``masses`` (N,) in units of the mean dot mass,
* ``segments`` (M, 4) px: the extra walls (box edges are implied by ``closed``),
* ``metadata``: one JSON string with ``format``, ``version``, the qdots and
  pymunk versions, ``time`` (s), ``start_time`` and ``steps_taken``, ``box``,
  ``closed``, ``restitution``, ``engine`` (the engine's settings, with its ``kind``), ``forces``
  (each ``Force.to_dict()``), ``rng`` (the NumPy bit generator state) and the
  collision counters.

Files written by 0.1 and 0.2 keep loading with the same meaning: a ``"CenterGravity"``
force (key ``center``) in the metadata's ``forces`` is read as today's
``"CentreGravity"`` (``centre``), the numerical knobs of 0.2's van der Waals
tables as engine settings, and the settings of the engine a run did not use
are dropped (`qdots.io.old_spellings`), without a warning. The ``qdots``
version a file holds says which behaviour wrote it (CHANGELOG.md).

Any NumPy can read it (``np.load(path)``; ``json.loads(str(f["metadata"]))``).
Files are written atomically (temporary file, then rename), so a crash
mid-write leaves the previous checkpoint intact.

Bit-identical resume. Chipmunk keeps a contact cache and a spatial index whose
shape depends on the run's history; neither can be written to a file. Saving
therefore *re-seats* the running simulation (`Simulation.reseat`): its space
is rebuilt from the saved arrays, exactly as `load` builds one. The run that
saved and any run resumed from the file then continue bit for bit alike. (A
run that never saved differs from them at round-off level from that moment.)
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import cast

import numpy as np
import pymunk

from labrig.archive import read_archive, write_archive
from labrig.files import recover_beside
from labrig.validate import InputError, count, flag, real, reals

from ..engine import ENGINES, engine_from_dict
from ..engine.contacts import stream_key
from ..forces import force_from_dict
from ..restitution import Restitution
from ..scene import MAX_DOTS, MAX_LENGTH, MAX_SEGMENTS, Scene
from ..simulation import Simulation
from ..state import State
from .old_spellings import current_engine, current_force, current_numerics

FORMAT = "qdots-state"
VERSION = 1
ARRAYS = ("positions", "velocities", "radii", "masses", "segments")
#: Keys of the saved collision counters (`qdots.engine.contacts.CollisionRecord`); files of 0.2 and
#: earlier have only the first three (their draws start from a key derived from the saved generator).
COUNTERS = ("dot_dot", "dot_wall", "sticking", "draws", "key")
OLD_COUNTERS = COUNTERS[:3]
#: Largest size of each saved array, bytes: float64 values of at most `qdots.scene.MAX_DOTS` dots and
#: `qdots.scene.MAX_SEGMENTS` walls (`labrig.archive.read_archive` refuses a file that declares more).
MAX_ARRAY_BYTES = {"positions": MAX_DOTS * 2 * 8, "velocities": MAX_DOTS * 2 * 8, "radii": MAX_DOTS * 8,
                   "masses": MAX_DOTS * 8, "segments": MAX_SEGMENTS * 4 * 8}


def save(sim: Simulation, path: str | os.PathLike, extra: dict | None = None) -> Path:
    """Write ``sim``'s board and everything needed to resume it to ``path`` (.npz), atomically.

    The simulation is re-seated afterwards (see the module docstring). Every board a simulation
    produces is saved and loads back, whatever its overlaps or dots that left an open board.
    ``extra`` adds keys to the metadata (JSON values; readers that do not know them ignore them).

    Returns
    -------
    pathlib.Path
        The path written.
    """
    from .. import __version__

    state = sim.state()
    scene = sim.scene
    metadata = {
        "format": FORMAT,
        "version": VERSION,
        "qdots": __version__,
        "pymunk": pymunk.version,
        "time": state.time,
        "start_time": sim.start_time,
        "steps_taken": sim.steps_taken,
        "box": list(scene.box),
        "closed": scene.closed,
        "restitution": {"mean": sim.restitution.mean, "wall": sim.restitution.wall,
                        "sticking_speed": sim.restitution.sticking_speed},
        "engine": sim.engine.to_dict(),
        "forces": [force.to_dict() for force in sim.forces],
        "rng": sim.rng.bit_generator.state,
        "collisions": sim.collisions.to_dict(),
    }
    for key, value in (extra or {}).items():
        if key in metadata:
            raise ValueError(f"extra metadata may not replace {key!r}")
        metadata[key] = value
    arrays = {"positions": state.positions, "velocities": state.velocities, "radii": state.radii,
              "masses": state.masses, "segments": scene.segments}
    path = write_archive(path, metadata, arrays)
    sim.reseat()
    return path


def save_board(state: State, path: str | os.PathLike, extra: dict | None = None) -> Path:
    """Write a board that no simulation produced (a film measured on a micrograph) as a state file.

    The file is an ordinary state file at time 0 of a simulation of that board with no forces and the
    default engine and collision rule: `read_state` reads it, ``qdots analyze`` and ``qdots render`` too,
    and `load` would start a run from it. ``extra`` adds metadata keys (see `save`).
    """
    box = cast("tuple[float, float]", tuple(state.box))  # (a State's box holds 2 numbers)
    scene = Scene(box=box, positions=state.positions, radii=state.radii, masses=state.masses,
                  velocities=state.velocities, segments=np.zeros((0, 4)), closed=state.closed, from_engine=True)
    return save(Simulation(scene, [], seed=0), path, extra)


def read_metadata(path: str | os.PathLike) -> dict:
    """The metadata of a state file (checked as `read_state` checks it), including any ``extra`` keys."""
    return _read(path)[0]


def _field(metadata: dict, key: str):
    if key not in metadata:
        raise InputError(f"metadata has no {key!r}")
    return metadata[key]


def _engine(metadata: dict) -> dict:
    """The saved engine table in today's spelling (`qdots.io.old_spellings.current_engine`), which holds at least
    the settings every version saved for its engine (``SAVED`` of `qdots.Chipmunk`, `qdots.Event`): a state
    resumes with the settings of the run that saved it, never silently with defaults."""
    engine = _field(metadata, "engine")
    if not isinstance(engine, dict):
        raise InputError(f"engine must be a table of engine settings, got {engine!r:.80}")
    engine = current_engine(engine)
    kind = engine.get("kind", "chipmunk")
    saved = ENGINES[kind].SAVED if isinstance(kind, str) and kind in ENGINES else ()
    missing = [key for key in saved if key not in engine]
    if missing:
        raise InputError(f"engine has no {', '.join(map(repr, missing))}: a state file holds the engine settings of "
                         f"the run that saved it (every version wrote {', '.join(saved)} for the {kind} engine)")
    return engine


def _read(path: str | os.PathLike) -> tuple[dict, Scene, Restitution]:
    """The checked metadata, the board and the collision rule of a state file, or an InputError that says what is
    wrong with it."""
    recover_beside(path)  # finish a switch of its output set that a kill interrupted (labrig.staging)
    metadata, arrays = read_archive(path, FORMAT, VERSION, ARRAYS, "qdots state", max_bytes=MAX_ARRAY_BYTES)
    try:
        time = real("time", _field(metadata, "time"), unit="s")
        start = real("start_time", _field(metadata, "start_time"), unit="s")
        steps = count("steps_taken", _field(metadata, "steps_taken"), 0)
        if not math.isclose(start + steps * engine_from_dict(_engine(metadata)).dt, time,
                            rel_tol=1e-9, abs_tol=1e-9):
            raise InputError(f"time {time!r} s is not start_time + steps_taken * dt")
        rule = _field(metadata, "restitution")
        if not isinstance(rule, dict) or sorted(rule) != ["mean", "sticking_speed", "wall"]:
            raise InputError(f"restitution must be a table of mean, wall and sticking_speed, got {rule!r}")
        restitution = Restitution(**rule)
        box = cast("tuple[float, float]", reals("box", _field(metadata, "box"), 2, 0.0, MAX_LENGTH))  # (2 numbers)
        scene = Scene(box=box, positions=arrays["positions"],
                      radii=arrays["radii"], masses=arrays["masses"], velocities=arrays["velocities"],
                      segments=arrays["segments"], closed=flag("closed", _field(metadata, "closed")),
                      from_engine=True)
    except InputError as exc:
        raise InputError(f"{path}: the saved board is invalid: {exc}") from None
    metadata["time"] = time
    return metadata, scene, restitution


def read_state(path: str | os.PathLike) -> State:
    """The board saved in ``path``, as a `State` for analysis and pictures (no engine built).

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    labrig.validate.InputError
        If the file is not a readable qdots state file (the message says why).
    """
    metadata, scene, _ = _read(path)
    assert scene.velocities is not None and scene.masses is not None  # (a Scene fills its defaults)
    return State(time=metadata["time"], positions=scene.positions.copy(), velocities=scene.velocities.copy(),
                 radii=scene.radii.copy(), masses=scene.masses.copy(), box=scene.box,
                 walls=scene.wall_segments().copy(), closed=scene.closed)


def load(path: str | os.PathLike) -> Simulation:
    """Rebuild the simulation saved in ``path``; it continues exactly as the run that saved it.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    labrig.validate.InputError
        If the file is truncated, corrupted, of another format or version,
        or holds invalid values; the message starts with the path.
    """
    metadata, scene, restitution = _read(path)
    try:
        forces = _field(metadata, "forces")
        if not isinstance(forces, list):
            raise InputError(f"forces must be a list of tables, got {forces!r}")
        forces, engine = current_numerics([current_force(spec) for spec in forces], metadata["engine"],
                                          restitution.sticking_speed)
        sim = Simulation(scene, [force_from_dict(spec) for spec in forces], restitution=restitution, seed=0,
                         engine=engine_from_dict(current_engine(engine)))
        rng = _field(metadata, "rng")
        try:
            sim.rng.bit_generator.state = rng
        except (TypeError, ValueError, KeyError, OverflowError) as exc:
            raise InputError(f"rng is not a state of numpy's {type(sim.rng.bit_generator).__name__}: {exc}") from None
        sim.steps_taken = metadata["steps_taken"]
        sim.start_time = metadata["start_time"]
        counters = _field(metadata, "collisions")
        if not isinstance(counters, dict) or sorted(counters) not in (sorted(COUNTERS), sorted(OLD_COUNTERS)):
            raise InputError(f"collisions must be a table of {', '.join(COUNTERS)}, got {counters!r}")
        sim.collisions.key = stream_key(sim.rng)
        for name in counters:
            setattr(sim.collisions, name, count(f"collisions.{name}", counters[name], 0, 2**64 - 1))
    except InputError as exc:
        raise InputError(f"{path}: the saved run is invalid: {exc}") from None
    return sim
