"""Progress bars say when numba compiles and leave the compiling time out of their rate and ETA."""

import io
import time

import numba

from labrig.progress import COMPILING, progress_bar


def fresh_kernel():
    @numba.njit(cache=False)
    def kernel(n):
        total = 0.0
        for i in range(n):
            total += i ** 0.5
        return total

    return kernel


def test_compilation_is_announced_once_and_left_out_of_the_rate():
    kernel, out = fresh_kernel(), io.StringIO()
    start = time.time()
    with progress_bar(10, unit="step", desc="demo", file=out, mininterval=0) as bar:
        for _ in range(10):
            kernel(100)  # the first call compiles
            time.sleep(0.02)
            bar.update(1)
        elapsed = bar.format_dict["elapsed"]
    wall = time.time() - start
    assert out.getvalue().count(COMPILING) == 1 and f"demo: {COMPILING}" in out.getvalue()
    assert bar.compile_seconds > 0
    # the bar's clock (its rate and ETA) ran without the compilation (to the time the bar itself takes, which a
    # loaded machine stretches)
    assert abs((wall - elapsed) - bar.compile_seconds) < 0.25 and elapsed >= 10 * 0.02


def test_nothing_is_said_when_nothing_compiles_and_the_listener_goes_with_the_bar():
    kernel = fresh_kernel()
    kernel(1)
    out = io.StringIO()
    with progress_bar(3, unit="step", desc="demo", file=out) as bar:
        kernel(5)
        bar.update(3)
    assert COMPILING not in out.getvalue() and bar.compile_seconds == 0.0
    other = fresh_kernel()
    other(1)  # compiles after the bar closed: the closed bar hears nothing
    assert bar.compile_seconds == 0.0


def test_a_hidden_bar_prints_nothing():
    out = io.StringIO()
    with progress_bar(3, unit="step", desc="demo", show=False, file=out) as bar:
        fresh_kernel()(3)
        bar.update(3)
    assert out.getvalue() == ""
