"""The engine layer: what a run needs while it runs, apart from the physics that says what acts.

* `qdots.engine.settings` -- `EngineSettings`, every numerical knob (time step, sub-steps, solver, the van der
  Waals pair list and its multiple time stepping), none of them physics;
* `qdots.engine.run` -- `ChipmunkEngine`: the space, the bodies, the collision record, the sub-step plan and
  each force's per-run cache of one simulation;
* `qdots.engine.event_run` -- `EventEngine`: the thesis's algorithm, exact hard discs event by event within
  frames at whose start the forces act (`qdots.engine.events`: the compiled event loop);
* `qdots.engine.stepping` -- one time step: the force phase and the sub-step plan;
* `qdots.engine.chipmunk` -- the Chipmunk adapter, the only module that reaches into pymunk's internals
  (tested pymunk versions, the public-API path otherwise);
* `qdots.engine.bodies` -- bulk reads and writes of the dots' positions and velocities;
* `qdots.engine.contacts` -- the collision rule run by Chipmunk as compiled callbacks, and its record;
* `qdots.engine.allocator` -- the allocator tuning a simulation opts into.
"""

from .event_run import EventEngine
from .run import ChipmunkEngine
from .settings import ENGINES, EngineSettings

#: The engine class of each `EngineSettings.kind`.
ENGINE_CLASSES = {"chipmunk": ChipmunkEngine, "event": EventEngine}

__all__ = ["ChipmunkEngine", "EventEngine", "EngineSettings", "ENGINES", "ENGINE_CLASSES"]
