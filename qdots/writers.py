"""When a simulation's writers write: one schedule of steps over successive runs.

A writer is anything with a ``write(state)`` method (a movie, a trajectory, a table). It is
attached to a `qdots.Simulation` once, with a trigger (every k steps, or every t seconds of
simulated time), and receives the state on that schedule in every later run. Steps are counted
from the simulation's step 0, so a deposition that makes hundreds of short runs still gives one
even comb of frames and never writes a step twice.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

from labrig.validate import InputError, count, real

from .state import State

#: Most states one writer may be given over a simulation's life, unless it states its own ``max_records``
#: (a trajectory of 1,000,000 frames of 300 dots holds about 5 GB).
MAX_RECORDS = 1_000_000


class Writer(Protocol):
    """Anything that records states during a run (movie, trajectory, table).

    A writer may state ``max_records``, the most states it takes (default `MAX_RECORDS`): a run that would
    give it more is refused before it starts.
    """

    def write(self, state: State) -> None: ...


@dataclass
class Attached:
    """A writer attached to a simulation: it gets the state every ``period`` steps (counted from step 0)."""

    writer: Writer
    period: int
    seconds: float | None = None  # given in seconds: the period follows the time step
    last: int = -1  # the step last written
    records: int = 0  # states given so far


def steps_in(seconds: float, dt: float) -> int:
    """Whole steps of ``dt`` closest to ``seconds`` (at least one)."""
    return max(1, round(real("seconds", seconds, 0.0, low_open=True) / dt))


class WriterSchedule:
    """The writers attached to one simulation and the steps at which each writes next."""

    def __init__(self) -> None:
        self._attached: list[Attached] = []

    def attach(self, writer, dt: float, every: int | None = None, seconds: float | None = None) -> None:
        """Add ``writer``: every ``every`` steps, every ``seconds`` of simulated time, or its own ``every``."""
        if not callable(getattr(writer, "write", None)):
            raise InputError(f"a writer needs a write(state) method, got {type(writer).__name__}")
        if every is not None and seconds is not None:
            raise InputError("give every (steps) or seconds, not both")
        if writer in self:
            raise InputError(f"{writer!r} is attached already")
        if seconds is not None:
            period = steps_in(seconds, dt)
        else:
            period = count("every", getattr(writer, "every", None) if every is None else every, 1)
        self._attached.append(Attached(writer, period, None if seconds is None else float(seconds)))

    def detach(self, writer) -> None:
        """Remove ``writer`` (it is not closed)."""
        if writer not in self:
            raise InputError(f"{writer!r} is not attached")
        self._attached = [a for a in self._attached if a.writer is not writer]

    def __contains__(self, writer) -> bool:
        return any(a.writer is writer for a in self._attached)

    @property
    def writers(self) -> tuple:
        """The attached writers, in the order they write."""
        return tuple(a.writer for a in self._attached)

    def restart(self, step: int, dt: float) -> None:
        """The step count restarts at 0 from ``step`` with a new time step ``dt``.

        A writer that wrote at ``step`` counts as having written step 0; a writer given in seconds
        keeps its interval in seconds.
        """
        for attached in self._attached:
            attached.last = 0 if attached.last == step else -1
            if attached.seconds is not None:
                attached.period = steps_in(attached.seconds, dt)

    def check_run(self, step: int, n_steps: int) -> None:
        """`InputError` when a run of ``n_steps`` steps from ``step`` would give a writer more states than its
        ``max_records`` (default `MAX_RECORDS`), counting those it has had."""
        for a in self._attached:
            due = (step + n_steps) // a.period - step // a.period + (step % a.period == 0 and a.last != step)
            limit = getattr(a.writer, "max_records", MAX_RECORDS)
            if a.records + due > limit:
                raise InputError(f"{type(a.writer).__name__} would get {a.records + due:,} states (one every {a.period:,} "
                                 f"steps over {n_steps:,} steps), more than the {limit:,} it takes: write less often")

    def next_due(self, step: int, end: int) -> int:
        """The first step after ``step`` at which a writer writes, or ``end`` if none comes before it."""
        return min([end, *(step + a.period - step % a.period for a in self._attached)])

    def write_due(self, step: int, state: Callable[[], State]) -> None:
        """Give each writer due at ``step`` (and not yet written there) the state ``state()``."""
        for attached in self._attached:
            if step % attached.period == 0 and attached.last != step:
                attached.writer.write(state())
                attached.last = step
                attached.records += 1
