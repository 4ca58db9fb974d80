"""planarize: anodization planarization of metal surfaces on height grids (thesis chapter 3).

>>> import planarize
>>> metal = planarize.surfaces.hill()                        # 17 x 17 points, 0.25 nm apart
>>> run = planarize.anodize(metal, thickness=1.0, model=planarize.Model(k_exp=2.3, step=0.01))  # doctest: +SKIP
>>> run.history["oxide_rms_nm"][-1]                        # doctest: +SKIP
"""

from labrig import __version__  # noqa: F401 (one version for the distribution)

from . import engines, surfaces
from .anodize import Anodization, Snapshot, anodize
from .engines import Fast, Matlab, Reference
from .metrics import rms, z_range
from .model import Model
from .heightfield import Surface

__all__ = ["Surface", "Model", "anodize", "Anodization", "Snapshot", "Fast", "Reference", "Matlab", "rms", "z_range",
           "surfaces", "engines"]
