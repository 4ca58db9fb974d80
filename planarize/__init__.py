"""planarize: anodization planarization of metal surfaces on height grids (thesis chapter 3).

>>> import planarize
>>> metal = planarize.surfaces.hill()                        # 17 x 17 points, 0.25 nm apart
>>> run = planarize.anodize(metal, thickness=1.0, model=planarize.Model(k_exp=2.3, step=0.01))  # doctest: +SKIP
>>> run.history["oxide_rms_nm"][-1]                        # doctest: +SKIP
"""

import importlib
import sys
import types

from labrig import __version__  # noqa: F401 (one version for the distribution)
from labrig.lazy import exports

#: Where each public name lives (imported when first used, so that ``planarize --help`` loads no engine).
_NAMES = {"Anodization": "anodize", "Snapshot": "anodize", "Continuum": "engines", "Fast": "engines",
          "Matlab": "engines", "Reference": "engines", "rms": "metrics", "z_range": "metrics", "Model": "model",
          "Surface": "heightfield"}
_MODULES = ("engines", "surfaces")

__all__ = ["Surface", "Model", "anodize", "Anodization", "Snapshot", "Continuum", "Fast", "Reference", "Matlab", "rms",
           "z_range", "surfaces", "engines"]


__getattr__, __dir__ = exports(__name__, _NAMES, _MODULES)


class _Package(types.ModuleType):
    """The package's module: ``planarize.anodize`` is the function, also once its module ``planarize/anodize.py``
    is imported (which makes the import system set the package's attribute of that name to the module; the
    module stays in ``sys.modules``)."""

    @property
    def anodize(self):
        return importlib.import_module(".anodize", __name__).anodize

    @anodize.setter
    def anodize(self, module) -> None:
        pass


sys.modules[__name__].__class__ = _Package
