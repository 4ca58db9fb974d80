"""Where a sweep's runs execute: this process, a local process pool, or a Dask cluster.

Each backend submits ``fn(*args)`` and returns a future, waits for the first to finish, says
whether an exception means its workers crashed, cancels, and closes. ``capacity`` is how many
runs it takes in flight.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import signal
import sys
import threading
import time
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool

from ..validate import InputError, count

#: Most local worker processes.
MAX_WORKERS = 256


class Serial:
    """Runs in this process, one at a time (``workers=1``): simplest to debug."""

    capacity = 1

    def submit(self, fn, *args) -> Future:
        future: Future = Future()
        future.set_result(fn(*args))
        return future

    def wait(self, futures):
        return set(futures)

    def crashed(self, exc) -> bool:
        return False

    def cancel(self, futures) -> None:
        pass

    def close(self) -> None:
        pass


#: How often a worker checks that the process that started it is alive, s.
PARENT_CHECK_INTERVAL = 1.0


def exit_with_parent(parent: int) -> None:
    """Make this worker process exit when ``parent`` (the sweep's process) dies, even by SIGKILL.

    On Linux the kernel sends the worker SIGKILL when its parent dies (``PR_SET_PDEATHSIG``);
    everywhere a daemon thread also checks every `PARENT_CHECK_INTERVAL` s that the parent is still
    its parent. A worker orphaned by a killed sweep would otherwise wait for work forever.
    """
    if sys.platform.startswith("linux"):
        with contextlib.suppress(OSError, AttributeError):
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(1, signal.SIGKILL, 0, 0, 0)  # PR_SET_PDEATHSIG
    if os.getppid() != parent:  # the parent died before the kernel was told
        os._exit(1)

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(PARENT_CHECK_INTERVAL)
        os._exit(1)

    threading.Thread(target=watch, name="labrig-parent-watch", daemon=True).start()


class LocalPool:
    """A `ProcessPoolExecutor` with at most ``workers`` runs in flight (so a crash has few suspects)."""

    def __init__(self, workers: int):
        self.capacity = workers
        self.pool: ProcessPoolExecutor | None = None

    def submit(self, fn, *args) -> Future:
        if self.pool is None:
            self.pool = ProcessPoolExecutor(max_workers=self.capacity, initializer=exit_with_parent,
                                            initargs=(os.getpid(),))
        return self.pool.submit(fn, *args)

    def wait(self, futures):
        return wait(futures, return_when=FIRST_COMPLETED).done

    def crashed(self, exc) -> bool:
        if isinstance(exc, BrokenProcessPool):
            self.cancel([])
            return True
        return False

    def cancel(self, futures) -> None:
        """Drop the pool without waiting (runs in progress finish in the background, unrecorded)."""
        if self.pool is not None:
            self.pool.shutdown(wait=False, cancel_futures=True)
            self.pool = None

    def close(self) -> None:
        if self.pool is not None:
            self.pool.shutdown()
            self.pool = None


class DaskCluster:
    """A Dask distributed cluster: ``scheduler`` is an address (``tcp://host:8786``) or a ``Client``."""

    capacity = float("inf")

    def __init__(self, scheduler):
        try:
            import distributed
        except ImportError:
            raise InputError("running on a Dask cluster needs dask.distributed: "
                             "pip install 'nanodisorder[sweep]'") from None
        self._wait = distributed.wait
        self.own = not isinstance(scheduler, distributed.Client)
        self.client = distributed.Client(scheduler) if self.own else scheduler

    def submit(self, fn, *args):
        return self.client.submit(fn, *args, pure=False)

    def wait(self, futures):
        return self._wait(futures, return_when="FIRST_COMPLETED").done

    def crashed(self, exc) -> bool:
        return False  # the scheduler reschedules tasks of lost workers itself (KilledWorker in the end)

    def cancel(self, futures) -> None:
        self.client.cancel(futures)

    def close(self) -> None:
        if self.own:
            self.client.close()


def make_backend(workers: int | None, scheduler):
    """Where runs go: a Dask cluster (``scheduler``), a local process pool, or this process (``workers=1``)."""
    if scheduler is not None:
        if workers is not None:
            raise InputError("give workers or scheduler, not both (a cluster has its own workers)")
        return DaskCluster(scheduler)
    if workers is None:
        workers = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    workers = count("workers", workers, 1, MAX_WORKERS)
    return Serial() if workers == 1 else LocalPool(workers)
