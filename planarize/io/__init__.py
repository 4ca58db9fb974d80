"""planarize files: measured height maps (`planarize.io.heights`, `planarize.io.gwy`, their length
units `planarize.io.units`), runs (`planarize.io.results`) and scene files (`planarize.io.scenefile`).

The height-map functions are also here: ``planarize.io.load_heights``, ``planarize.io.save_heights``.
"""

from .heights import FORMATS, SUFFIXES, level_plane, load_heights, save_heights
from .units import LENGTH_UNITS, unit_scale

__all__ = ["load_heights", "save_heights", "level_plane", "unit_scale", "FORMATS", "LENGTH_UNITS", "SUFFIXES"]
