"""Keep numpy's large temporaries on the heap (glibc only; speed, not results).

Per-pair arrays of a few hundred kB exceed glibc's default mmap threshold
(128 kB), so every temporary is a fresh mapping whose pages fault on first
touch, and freed heap tops are trimmed back to the OS. Where page faults are
expensive (sandboxes, some VMs) this made a 3,000-dot van der Waals step 3x
slower (4.0 ms vs 1.3 ms measured here). Raising the mmap and trim thresholds
lets freed blocks be reused. The cost is that the process keeps its peak heap.

Applied once at import of `qdots`; set ``QDOTS_KEEP_MALLOC=1`` in the
environment to leave the allocator alone.
"""

from __future__ import annotations

import ctypes
import os
import sys

_M_TRIM_THRESHOLD = -1
_M_MMAP_THRESHOLD = -3
MMAP_THRESHOLD_BYTES = 256 * 1024 * 1024
TRIM_THRESHOLD_BYTES = 512 * 1024 * 1024


def tune_allocator() -> bool:
    """Raise glibc's mmap/trim thresholds. Returns True if applied."""
    if os.environ.get("QDOTS_KEEP_MALLOC") or not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL("libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):  # musl or another libc: nothing to tune
        return False
    return bool(mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES)) and bool(
        mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES)
    )


ALLOCATOR_TUNED = tune_allocator()
