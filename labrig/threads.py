"""Threads for compiled kernels: a pool per thread count, and work split by rows, by chunks or into tasks.

The kernels are compiled with the GIL released (`labrig.compiled.jit`), so Python threads run them
side by side (planarize's engines split a height grid by rows, qdots measure a film's dots by strips and chunks, and
its trial fits as tasks that each thread takes in turn, `run_tasks`). Threads, not
numba's parallel loops: a sweep's worker processes are forked, and a forked child has none of its parent's threads
(the pools are dropped after a fork and made again).
"""

from __future__ import annotations

import functools
import itertools
import os
import threading
from concurrent.futures import ThreadPoolExecutor


def available_threads() -> int:
    """The CPUs this process may use."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


#: The names of the pools' threads begin so.
POOL_PREFIX = "labrig"


@functools.cache
def thread_pool(threads: int) -> ThreadPoolExecutor:
    """One pool per thread count, kept for the life of the process (a pool per call costs more than a call)."""
    return ThreadPoolExecutor(threads, thread_name_prefix=POOL_PREFIX)


if hasattr(os, "register_at_fork"):  # a forked child (e.g. a sweep worker) has none of the pools' threads
    os.register_at_fork(after_in_child=thread_pool.cache_clear)


def run_in_threads(function, parts: list) -> list:
    """``function(part)`` for each of ``parts``, in threads when there are several; this thread takes the first. Called
    from one of the pools' threads (work nested in work already side by side), the parts run one after the other: a
    pool's thread waiting for its own pool could wait for ever."""
    if threading.current_thread().name.startswith(POOL_PREFIX):
        return [function(part) for part in parts]
    rest = [thread_pool(len(parts) - 1).submit(function, part) for part in parts[1:]]
    return [function(parts[0])] + [future.result() for future in rest]


def run_tasks(tasks: list, threads: int | None = None) -> list:
    """Each of ``tasks`` (callables without arguments) called once, side by side in up to ``threads`` threads (default
    `available_threads`), each thread taking the next task not yet taken (tasks of uneven cost keep every thread busy);
    their results in the tasks' order. The result does not depend on the number of threads when no task depends on
    another."""
    threads = max(1, min(available_threads() if threads is None else threads, len(tasks)))
    if threads == 1:
        return [task() for task in tasks]
    results: list = [None] * len(tasks)
    taken = itertools.count()  # next() of a count is atomic: no two threads take one task
    failed: list = []  # once a task raises, the other threads take no more

    def work(_):
        for index in taken:
            if index >= len(tasks) or failed:
                return
            try:
                results[index] = tasks[index]()
            except BaseException:
                failed.append(index)
                raise

    run_in_threads(work, list(range(threads)))
    return results


def by_chunks(function, n: int, chunk: int = 1024) -> list:
    """``function(start, stop)`` for consecutive chunks of ``range(n)`` of ``chunk`` items (the last shorter), side by
    side in threads (`run_tasks`), their results in order: for work item by item (dots, say) whose items do not
    depend on each other."""
    return run_tasks([lambda start=start: function(start, min(start + chunk, n)) for start in range(0, n, chunk)])


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
