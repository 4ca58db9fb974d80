"""qdots: quantum-dot monolayer packing on pymunk (thesis chapter 2).

>>> import qdots
>>> scene = qdots.Scene(box=(100, 100), positions=[[30, 50], [70, 50]], radii=[7.5, 7.5],
...                     velocities=[[20, 0], [-20, 0]])
>>> sim = qdots.Simulation(scene, [qdots.VanDerWaals()], seed=1)
>>> state = sim.run(1.0)
"""

from labrig import __version__  # noqa: F401 (one version for the distribution)
from labrig.deprecation import alias_modules, renamed_attributes

from ._malloc import ALLOCATOR_TUNED
from .collisions import Restitution
from . import forces
from .forces import (  # noqa: F401 (exported as forces.FORCE_TYPES in __all__)
    CentreGravity, Drag, Force, Gravity, Langevin, ThermalKicks, VanDerWaals)
from .io.checkpoint import load, read_state, save
from .scene import Scene, grating_segments
from .simulation import EngineSettings, Simulation
from .state import State

# modules that moved in 0.2 (their old names warn, and go in the next release)
alias_modules({f"qdots.{old}": new for old, new in {
    "structure": "qdots.analysis.structure", "forster": "qdots.analysis.forster", "lqe": "qdots.analysis.lqe",
    "lqe_thesis": "qdots.analysis.lqe_thesis", "report": "qdots.analysis.report",
    "checkpoint": "qdots.io.checkpoint", "scenefile": "qdots.io.experiment_file",
    "trajectory": "qdots.io.trajectory", "live": "qdots.interactive.live", "experiment_sweep": "qdots.cli.sweep",
    "commands": "qdots.cli.commands", "neighbors": "qdots.neighbours", "sweeps": "labrig.sweeps",
    "atomic": "labrig.files", "tomlfile": "labrig.tomlfile", "cliutil": "labrig.cli"}.items()})

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
    "ALLOCATOR_TUNED",
]
__getattr__ = renamed_attributes(__name__, {"CenterGravity": "CentreGravity"})
