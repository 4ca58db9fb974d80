"""How hot loops are compiled: one numba decorator with the project's settings.

numba is a core dependency. Every compiled function is cached on disk (the first run compiles,
later ones load), releases the GIL (threads can share the work) and follows numpy's error model (a
division by zero gives inf or nan, as the same expression on arrays would, instead of raising).

`c_callback` compiles a function that C code calls through a function pointer (a library's
callback slot), and `pointer` turns a memory address into a pointer such a function can read
with ``numba.carray``.
"""

from __future__ import annotations

import functools

import numba
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic


def jit(function=None, *, inline: bool = False):
    """Compile ``function`` with numba (``@jit`` or ``@jit(inline=True)``).

    ``inline=True`` inlines it into its compiled callers: for small helpers called per element with
    many array arguments, where a call costs more than the work.
    """
    if function is None:
        return functools.partial(jit, inline=inline)
    return numba.njit(cache=True, nogil=True, error_model="numpy", inline="always" if inline else "never")(function)


def c_callback(signature: str):
    """Compile a function with a C signature (e.g. ``"void(voidptr, voidptr, voidptr)"``); its
    ``.address`` is the C function pointer."""
    return numba.cfunc(signature, cache=True, error_model="numpy")  # compiled without Python objects, as every cfunc


@intrinsic
def pointer(typingctx, address):
    """The memory address ``address`` (an unsigned integer) as a ``void *`` (compiled code only)."""

    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], cgutils.voidptr_t)

    return types.voidptr(address), codegen
