"""qdots: quantum-dot monolayer packing (thesis chapter 2), on pymunk or on the thesis's event-driven algorithm.

>>> import qdots
>>> scene = qdots.Scene(box=(100, 100), positions=[[30, 50], [70, 50]], radii=[7.5, 7.5],
...                     velocities=[[20, 0], [-20, 0]])
>>> sim = qdots.Simulation(scene, [qdots.VanDerWaals()], seed=1, engine=qdots.Chipmunk())
>>> state = sim.run(1.0)

The names below are imported when first used, so that ``import qdots`` (and the command line's ``--help``)
does not load the simulators.
"""

from __future__ import annotations

import warnings

from labrig import __version__  # noqa: F401 (one version for the distribution)
from labrig.lazy import exports

#: Where each public name lives.
_NAMES = {
    "Scene": "scene", "grating_segments": "scene",
    "Simulation": "simulation",
    "Chipmunk": "engine", "Event": "engine",
    "save": "io.checkpoint", "load": "io.checkpoint", "read_state": "io.checkpoint",
    "State": "state",
    "Restitution": "restitution",
    "Force": "forces", "VanDerWaals": "forces", "ThermalKicks": "forces", "Langevin": "forces", "Drag": "forces",
    "Gravity": "forces", "CentreGravity": "forces",
}
#: Subpackages reachable as attributes (``qdots.forces.VanDerWaals``).
_MODULES = ("forces", "engine", "analysis", "geometry", "io", "diagnostics")

__all__ = [
    "Scene",
    "Simulation",
    "Chipmunk",
    "Event",
    "save",
    "load",
    "read_state",
    "State",
    "Restitution",
    "Force",
    "VanDerWaals", "ThermalKicks", "Langevin", "Drag", "Gravity", "CentreGravity",  # qdots.forces.FORCE_TYPES
    "grating_segments",
]


_lazy_getattr, __dir__ = exports(__name__, _NAMES, _MODULES)


def __getattr__(name: str):
    if name == "EngineSettings":
        warnings.warn("qdots.EngineSettings is deprecated since 0.3 and goes in 0.4: use qdots.Chipmunk(...) or "
                      "qdots.Event(...)", DeprecationWarning, stacklevel=2)
        return _engine_settings
    return _lazy_getattr(name)


def _engine_settings(**settings):
    """What ``EngineSettings(**settings)`` of 0.2 meant: the settings of the engine ``kind`` (default chipmunk); the
    other engine's settings, which 0.2 took and that engine never read, are checked and dropped."""
    from .engine import engine_from_dict
    from .io.old_spellings import current_engine

    return engine_from_dict(current_engine(settings))
