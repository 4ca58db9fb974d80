"""How hot loops are compiled: one numba decorator with the project's settings.

numba is a core dependency. Every compiled function is cached on disk (the first run compiles,
later ones load), releases the GIL (threads can share the work) and follows numpy's error model (a
division by zero gives inf or nan, as the same expression on arrays would, instead of raising).
"""

from __future__ import annotations

import functools

import numba


def jit(function=None, *, inline: bool = False):
    """Compile ``function`` with numba (``@jit`` or ``@jit(inline=True)``).

    ``inline=True`` inlines it into its compiled callers: for small helpers called per element with
    many array arguments, where a call costs more than the work.
    """
    if function is None:
        return functools.partial(jit, inline=inline)
    return numba.njit(cache=True, nogil=True, error_model="numpy", inline="always" if inline else "never")(function)
