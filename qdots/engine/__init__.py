"""The engines: what moves the dots between the forces' velocity changes, each with its own settings class.

* `Chipmunk` (`qdots.engine.chipmunk`) -- Chipmunk's impulse solver (pymunk) in sub-steps planned for the
  approach speeds: the default;
* `Event` (`qdots.engine.event`) -- the thesis's own algorithm, exact hard discs event by event within frames
  at whose start the forces act.

An engine's settings are frozen and checked when made; each builds its engine for a simulation, a `Backend`
(`qdots.engine.protocol`, the engine protocol): `qdots.engine.chipmunk_backend.ChipmunkBackend` (the space,
the bodies, the sub-step plan of `qdots.engine.chipmunk_step`; `qdots.engine.pymunk_adapter` is the one
module that reaches into pymunk, `qdots.engine.bodies` its bulk reads and writes, `qdots.engine.contacts` the
collision rule as compiled callbacks and the collision record) or `qdots.engine.event_backend.EventBackend`
(the compiled event loop of `qdots.engine.event_loop`). Both evaluate the pair forces with a `PairScheme`
(`qdots.engine.pair_scheme`); `qdots.engine.allocator` is the allocator tuning a simulation opts into.

This package imports no simulator code until an engine is built: the command line reads `ENGINES` at once.
"""

from labrig.params import Param

from .chipmunk import Chipmunk
from .event import Event
from .pair_scheme import PairScheme
from .protocol import Backend
from .settings import Settings, engine_class, engine_from_dict

#: The engines' settings classes by name (``[engine] kind`` in files, ``--engine`` on the command line).
ENGINES: dict[str, type[Settings]] = {cls.kind: cls for cls in (Chipmunk, Event)}

#: Declaration of ``kind``, the key of an ``[engine]`` table that says which engine its other keys set.
KIND = Param("str", choices=tuple(ENGINES), doc="the engine: Chipmunk's solver or the thesis's events")


def engine_params(settings: Settings) -> dict[str, Param]:
    """The declarations of an ``[engine]`` table holding ``settings``: `KIND`, then its engine's fields."""
    return {"kind": KIND, **type(settings).PARAMS}


__all__ = ["Chipmunk", "Event", "Settings", "PairScheme", "Backend", "ENGINES", "KIND", "engine_class", "engine_from_dict",
           "engine_params"]
