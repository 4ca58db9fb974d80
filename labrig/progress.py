"""Progress bars that say when numba compiles and keep compilation out of their ETA.

The first run on a machine compiles every numba kernel it reaches (later runs load them from the disk cache,
`labrig.compiled`). Inside a progress bar that time would look like slow steps: the first rate shown would be
many times too slow and the ETA hours too long. `progress_bar` is a ``tqdm.auto`` bar that listens to numba's
compile events while it is open: it prints one line when compilation starts and leaves the compiling time out
of its rate, so the ETA is that of the run itself. Its elapsed time is then the time spent running.
"""

from __future__ import annotations

import time

from numba.core import event
from tqdm.auto import tqdm

#: The line a bar prints when numba starts compiling under it.
COMPILING = "compiling the numba kernels (first run only: later runs load them from the disk cache)"


class _CompileClock(event.Listener):
    """Seconds of top-level numba compilation seen while a bar is open."""

    def __init__(self, bar: "CompileAwareBar"):
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
