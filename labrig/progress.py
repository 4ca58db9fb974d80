"""Progress bars that say when numba compiles and keep compilation out of their ETA.

The first run on a machine compiles every numba kernel it reaches (later runs load them from the disk cache,
`labrig.compiled`). Inside a progress bar that time would look like slow steps: the first rate shown would be
many times too slow and the ETA hours too long. `progress_bar` is a ``tqdm.auto`` bar that listens to numba's
compile events while it is open: it prints one line when compilation starts and leaves the compiling time out
of its rate, so the ETA is that of the run itself. Its elapsed time is then the time spent running.
"""

from __future__ import annotations

import sys
import time

from numba.core import event
from tqdm.auto import tqdm

#: The line a bar prints when numba starts compiling under it.
COMPILING = "compiling the numba kernels (first run only: later runs load them from the disk cache)"


class _CompileClock(event.Listener):
    """Seconds of top-level numba compilation seen while a bar is open."""

    def __init__(self, bar: CompileAwareBar | StageLines):
        self.bar = bar
        self.depth = 0
        self.started = 0.0
        self.seconds = 0.0

    def on_start(self, ev) -> None:
        if self.depth == 0:
            self.started = time.time()
            self.bar.compiling()
        self.depth += 1

    def on_end(self, ev) -> None:
        self.depth -= 1
        if self.depth == 0:
            spent = time.time() - self.started
            self.seconds += spent
            self.bar.leave_out(spent)


class CompileAwareBar(tqdm):
    """A ``tqdm.auto`` bar that announces numba compilation and leaves it out of its rate and ETA.

    Attributes
    ----------
    compile_seconds : float
        Wall seconds numba spent compiling while the bar was open.
    """

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._announced = False
        self._clock = _CompileClock(self)
        self._listening = True
        event.register("numba:compile", self._clock)

    @property
    def compile_seconds(self) -> float:
        return self._clock.seconds

    def compiling(self) -> None:
        """Say once that numba is compiling."""
        if not self._announced and not self.disable:
            self._announced = True
            self.write(f"{self.desc or 'run'}: {COMPILING}", file=self.fp)

    def leave_out(self, seconds: float) -> None:
        """Shift the bar's clocks by ``seconds`` spent compiling, so its rate and ETA leave them out."""
        if not self.disable:
            self.start_t += seconds
            self.last_print_t += seconds

    def close(self) -> None:
        if getattr(self, "_listening", False):
            self._listening = False
            event.unregister("numba:compile", self._clock)
        super().close()


#: A run of stages that ends within this many seconds prints no stage line (`StageLines`).
QUIET = 5.0


class StageLines:
    """Progress of a run of stages as plain lines, for logs and pipes, where a bar would redraw in place.

    It takes a bar's calls (``set_postfix_str(stage)`` names the stage that starts, ``update()`` marks it). A run
    that ends within `QUIET` s prints nothing; after that, each stage that starts prints one line,
    ``DESC: STAGE (T s)``, with the time spent compiling numba's kernels said once (the first run on a machine).

    Parameters
    ----------
    desc : str
        What runs, the start of each line (``"qdots measure"``).
    stream : file, optional
        Where the lines go (default stderr).
    quiet : float, optional
        Seconds before the first line (default `QUIET`).
    """

    def __init__(self, desc: str, stream=None, quiet: float | None = None):
        self.desc, self.stream, self.quiet = desc, stream, QUIET if quiet is None else quiet
        self.stage = ""
        self.start = time.perf_counter()
        self.compile_seconds = 0.0
        self._said_compile = False
        self._clock = _CompileClock(self)
        self._listening = True
        event.register("numba:compile", self._clock)

    def compiling(self) -> None:
        """numba started compiling (said with the next line)."""

    def leave_out(self, seconds: float) -> None:
        self.compile_seconds += seconds

    def set_postfix_str(self, stage: str, refresh: bool = False) -> None:
        self.stage = stage

    def update(self, n: float = 1) -> None:
        elapsed = time.perf_counter() - self.start
        if elapsed < self.quiet or not self.stage:
            return
        note = ""
        if self.compile_seconds and not self._said_compile:
            self._said_compile = True
            note = f", of which {self.compile_seconds:.0f} s {COMPILING.split(' (')[0]}, first run only"
        print(f"{self.desc}: {self.stage} ({elapsed:.0f} s{note})", file=self.stream or sys.stderr, flush=True)

    def close(self) -> None:
        if self._listening:
            self._listening = False
            event.unregister("numba:compile", self._clock)

    def __enter__(self) -> StageLines:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def progress_bar(total: float, *, unit: str, desc: str, show: bool = True, **options) -> CompileAwareBar:
    """A progress bar over ``total`` ``unit`` s (`CompileAwareBar`); ``show=False`` makes one that prints nothing.

    Parameters
    ----------
    total : float
        What a finished run counts (steps, nm, runs).
    unit, desc : str
        tqdm's unit and label.
    show : bool
        False: a disabled bar (nothing printed), so callers need no branch.
    **options
        Other tqdm options (``leave``, ``bar_format``, ``initial``, ...).
    """
    return CompileAwareBar(total=total, unit=unit, desc=desc, disable=not show, **options)


def duration(seconds: float) -> str:
    """``seconds`` as a person reads a duration: "45 s", "12 min", "3.5 h", "2.1 days"."""
    if seconds < 90:
        return f"{seconds:.2g} s" if seconds < 10 else f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h" if seconds < 48 * 3600 else f"{seconds / 86400:.1f} days"
