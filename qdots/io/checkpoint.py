"""Saving and resuming boards: one ``.npz`` file per checkpoint.

Format (``format = "qdots-state"``, ``version = 1``): a NumPy ``.npz`` archive
(uncompressed zip) with the arrays

* ``positions`` (N, 2) px, ``velocities`` (N, 2) px/s,
* ``radii`` (N,) px, ``masses`` (N,) in units of the mean dot mass,
* ``segments`` (M, 4) px: the extra walls (box edges are implied by ``closed``),
* ``metadata``: one JSON string with ``format``, ``version``, the qdots and
  pymunk versions, ``time`` (s), ``start_time`` and ``steps_taken``, ``box``,
  ``closed``, ``restitution``, ``engine`` (the `EngineSettings`), ``forces``
  (each ``Force.to_dict()``), ``rng`` (the NumPy bit generator state) and the
  collision counters.

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

import json
import os
import zipfile
from pathlib import Path

import numpy as np
import pymunk

from labrig.files import atomic_path
from labrig.validate import InputError

from ..collisions import Restitution
from ..forces import force_from_dict
from ..scene import Scene
from ..simulation import ENGINE_OVERLAP_TOLERANCE, Simulation
from ..state import State

FORMAT = "qdots-state"
VERSION = 1
ARRAYS = ("positions", "velocities", "radii", "masses", "segments")


def save(sim: Simulation, path: str | os.PathLike) -> Path:
    """Write ``sim``'s board and everything needed to resume it to ``path`` (.npz), atomically.

    The simulation is re-seated afterwards (see the module docstring).

    Returns
    -------
    pathlib.Path
        The path written.
    """
    state = sim.state()
    scene = sim.scene
    metadata = {
        "format": FORMAT,
        "version": VERSION,
        "qdots": _qdots_version(),
        "pymunk": pymunk.version,
        "time": state.time,
        "start_time": sim.start_time,
        "steps_taken": sim.steps_taken,
        "box": list(scene.box),
        "closed": scene.closed,
        "restitution": {"mean": scene.restitution.mean, "wall": scene.restitution.wall,
                        "sticking_speed": scene.restitution.sticking_speed},
        "engine": sim.settings.to_dict(),
        "forces": [force.to_dict() for force in sim.forces],
        "rng": sim.rng.bit_generator.state,
        "collisions": {"dot_dot": sim.collisions.dot_dot, "dot_wall": sim.collisions.dot_wall,
                       "sticking": sim.collisions.sticking},
    }
    arrays = {"positions": state.positions, "velocities": state.velocities, "radii": state.radii,
              "masses": state.masses, "segments": scene.segments}
    path = Path(path)
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as stream:  # a file object stops np.savez appending ".npz"
            np.savez(stream, metadata=np.array(json.dumps(metadata)), **arrays)
    sim.reseat()
    return path


def _qdots_version() -> str:
    from .. import __version__

    return __version__


def _read(path: str | os.PathLike) -> tuple[dict, dict[str, np.ndarray]]:
    """Metadata and arrays of a state file, or a ValueError that says what is wrong with it."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"no such state file: {path}")
    try:
        with np.load(path, allow_pickle=False) as archive:
            missing = [name for name in ("metadata", *ARRAYS) if name not in archive.files]
            if missing:
                raise InputError(f"missing {', '.join(missing)}")
            arrays = {name: archive[name] for name in ARRAYS}
            metadata = json.loads(str(archive["metadata"]))
    except (zipfile.BadZipFile, EOFError, OSError, ValueError, KeyError, json.JSONDecodeError) as exc:
        raise InputError(f"{path} is not a readable qdots state file ({type(exc).__name__}: {exc})") from None
    if not isinstance(metadata, dict) or metadata.get("format") != FORMAT:
        raise InputError(f"{path} is not a qdots state file (format {metadata.get('format')!r})")
    if metadata.get("version") != VERSION:
        raise InputError(f"{path} has state format version {metadata.get('version')!r}; "
                         f"this qdots reads version {VERSION}")
    return metadata, arrays


def read_state(path: str | os.PathLike) -> State:
    """The board saved in ``path``, as a `State` for analysis and pictures (no engine built)."""
    metadata, arrays = _read(path)
    scene = _scene(metadata, arrays, path)
    return State(time=float(metadata["time"]), positions=scene.positions.copy(),
                 velocities=scene.velocities.copy(), radii=scene.radii.copy(), masses=scene.masses.copy(),
                 box=scene.box, walls=scene.wall_segments().copy())


def _scene(metadata: dict, arrays: dict[str, np.ndarray], path: str | os.PathLike) -> Scene:
    try:
        return Scene(box=tuple(metadata["box"]), positions=arrays["positions"], radii=arrays["radii"],
                     masses=arrays["masses"], velocities=arrays["velocities"], segments=arrays["segments"],
                     closed=bool(metadata["closed"]), restitution=Restitution(**metadata["restitution"]),
                     overlap_tolerance=ENGINE_OVERLAP_TOLERANCE)
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(f"{path}: saved board is invalid ({exc})") from None


def load(path: str | os.PathLike) -> Simulation:
    """Rebuild the simulation saved in ``path``; it continues exactly as the run that saved it.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        If the file is truncated, corrupted, of another format or version,
        or holds an invalid board.
    """
    metadata, arrays = _read(path)
    scene = _scene(metadata, arrays, path)
    try:
        engine = dict(metadata["engine"])
        forces = [force_from_dict(spec) for spec in metadata["forces"]]
        sim = Simulation(scene, forces, seed=0, **engine)
        sim.rng.bit_generator.state = metadata["rng"]
        sim.steps_taken = int(metadata["steps_taken"])
        sim.start_time = float(metadata["start_time"])
        for name, count in metadata["collisions"].items():
            setattr(sim.collisions, name, int(count))
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(f"{path}: saved run is invalid ({type(exc).__name__}: {exc})") from None
    return sim
