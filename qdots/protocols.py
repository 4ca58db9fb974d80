"""The deprecated name of `qdots.deposition` (the thesis's deposition protocols), until 0.4.

Importing it warns; every name is `qdots.deposition`'s.
"""

import warnings

from . import deposition

warnings.warn("qdots.protocols is now qdots.deposition (the same names); qdots.protocols goes in 0.4",
              DeprecationWarning, stacklevel=2)


def __getattr__(name: str):
    """``qdots.protocols.NAME`` is ``qdots.deposition.NAME``."""
    return getattr(deposition, name)
