"""qdots: quantum-dot monolayer packing on pymunk (thesis chapter 2).

>>> import qdots
>>> scene = qdots.Scene(box=(100, 100), positions=[[30, 50], [70, 50]], radii=[7.5, 7.5],
...                     velocities=[[20, 0], [-20, 0]])
>>> sim = qdots.Simulation(scene, [qdots.VanDerWaals()], seed=1)
>>> state = sim.run(1.0)
"""

from labrig import __version__  # noqa: F401 (one version for the distribution)

from .restitution import Restitution
from . import forces
from .forces import (  # noqa: F401 (exported as forces.FORCE_TYPES in __all__)
    CentreGravity, Drag, Force, Gravity, Langevin, ThermalKicks, VanDerWaals)
from .io.checkpoint import load, read_state, save
from .scene import Scene, grating_segments
from .engine import EngineSettings
from .simulation import Simulation
from .state import State

__all__ = [
    "Scene",
    "Simulation",
    "EngineSettings",
    "save",
    "load",
    "read_state",
    "State",
    "Restitution",
    "Force",
    *forces.FORCE_TYPES,  # the built-in forces
    "grating_segments",
]
