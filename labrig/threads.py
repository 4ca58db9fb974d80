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


#: Rows of the bands `by_rows` cuts an image into: fixed, so that a result never depends on the number of threads.
BAND_ROWS = 512


def by_rows(function, image, margin: int, band: int = BAND_ROWS):
    """``function(image)`` computed on bands of ``band`` rows, each with up to ``margin`` more rows of ``image``
    either side, side by side in threads, and put together. Equal to ``function(image)`` wherever its value at a
    pixel depends only on the pixels within ``margin`` rows of it (a filter whose footprint reaches at most
    ``margin``). ``function`` maps an array to one of the same number of rows (numpy releases the GIL in most
    filters, so the bands run at once). An image of fewer than two bands is computed whole."""
    import numpy as np

    rows = image.shape[0]
    margin = max(0, int(margin))
    if rows < 2 * band:
        return function(image)
    starts = list(range(0, rows, band))

    def bands(chosen):
        out = []
        for start in chosen:
            low, stop = max(0, start - margin), min(rows, start + band)
            out.append(function(image[low:min(rows, stop + margin)])[start - low:stop - low])
        return out

    threads = max(1, min(available_threads(), len(starts)))
    parts = [starts[len(starts) * p // threads:len(starts) * (p + 1) // threads] for p in range(threads)]
    return np.concatenate([piece for part in run_in_threads(bands, parts) for piece in part])
