"""Keep numpy's large temporaries on the heap (glibc only; speed, never results): an explicit call.

Per-pair arrays of a few hundred kB exceed glibc's default mmap threshold (128 kB), so every temporary
is a fresh mapping whose pages fault on first touch, and freed heap tops are trimmed back to the OS.
Where page faults are expensive (sandboxes, some VMs) that makes large van der Waals steps several times
slower; where they are cheap it changes nothing (the measurements: docs/performance.md, "Allocator").
Raising the mmap and trim thresholds lets freed blocks be reused; the cost is that the process keeps its
peak heap.

Nothing happens at import. A simulation whose engine settings say ``tune_allocator=True`` (the default of
`qdots.Chipmunk` and `qdots.Event`) calls `tune_allocator` when it is built, once per process; set
``QDOTS_KEEP_MALLOC=1`` in the environment to leave the allocator alone whatever the settings say.
"""

from __future__ import annotations

import ctypes
import functools
import os
import sys

_M_TRIM_THRESHOLD = -1
_M_MMAP_THRESHOLD = -3
#: The thresholds set, bytes.
MMAP_THRESHOLD_BYTES = 256 * 1024 * 1024
TRIM_THRESHOLD_BYTES = 512 * 1024 * 1024


@functools.cache
def tune_allocator() -> bool:
    """Raise glibc's mmap and trim thresholds for this process (once); True if applied.

    Nothing is done (False) outside Linux, with another C library than glibc, or with ``QDOTS_KEEP_MALLOC``
    set in the environment.
    """
    if os.environ.get("QDOTS_KEEP_MALLOC") or not sys.platform.startswith("linux"):
        return False
    try:
        mallopt = ctypes.CDLL("libc.so.6").mallopt
    except (OSError, AttributeError):  # musl or another libc: nothing to tune
        return False
    return bool(mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES)) and bool(
        mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES)
    )
