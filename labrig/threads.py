"""Threads for compiled kernels: a pool per thread count, and work split by rows.

The kernels are compiled with the GIL released (`labrig.compiled.jit`), so Python threads run them
side by side (planarize's engines split a height grid by rows, qdots measure a film's dots by strips). Threads, not
numba's parallel loops: a sweep's worker processes are forked, and a forked child has none of its parent's threads
(the pools are dropped after a fork and made again).
"""

from __future__ import annotations

import functools
import os
from concurrent.futures import ThreadPoolExecutor


def available_threads() -> int:
    """The CPUs this process may use."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


@functools.cache
def thread_pool(threads: int) -> ThreadPoolExecutor:
    """One pool per thread count, kept for the life of the process (a pool per call costs more than a call)."""
    return ThreadPoolExecutor(threads, thread_name_prefix="labrig")


if hasattr(os, "register_at_fork"):  # a forked child (e.g. a sweep worker) has none of the pools' threads
    os.register_at_fork(after_in_child=thread_pool.cache_clear)


def run_in_threads(function, parts: list) -> list:
    """``function(part)`` for each of ``parts``, in threads when there are several; this thread takes the first."""
    rest = [thread_pool(len(parts) - 1).submit(function, part) for part in parts[1:]]
    return [function(parts[0])] + [future.result() for future in rest]


def row_ranges(rows: int, threads: int, least: int = 16) -> list[tuple[int, int]]:
    """``range(rows)`` as consecutive (start, stop) ranges, one per thread, each of at least ``least`` rows."""
    parts = max(1, min(threads, rows // max(least, 1)))
    return [(rows * p // parts, rows * (p + 1) // parts) for p in range(parts)]
