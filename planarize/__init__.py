"""planarize: anodization planarization of metal surfaces on height grids (thesis chapter 3).

>>> import planarize
>>> metal = planarize.scenes.hill()                        # 17 x 17 points, 0.25 nm apart
>>> run = planarize.anodize(metal, thickness=1.0)          # doctest: +SKIP
>>> run.history["oxide_rms_nm"][-1]                        # doctest: +SKIP
"""

from . import scenes
from .anodize import Anodization, Snapshot, anodize, engines
from .metrics import rms, z_range
from .surface import Surface

from labrig import __version__  # noqa: E402,F401 (one version for the distribution)

__all__ = ["Surface", "anodize", "Anodization", "Snapshot", "engines", "rms", "z_range", "scenes"]
