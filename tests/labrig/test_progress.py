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


def test_stage_lines_are_quiet_for_a_short_run_then_one_per_stage_with_the_compile_said_once():
    from labrig.progress import StageLines

    out = io.StringIO()
    with StageLines("demo", stream=out) as lines:  # a run within QUIET s says nothing
        for stage in ("reading", "finding"):
            lines.set_postfix_str(stage)
            lines.update()
    assert out.getvalue() == ""
    kernel = fresh_kernel()
    with StageLines("demo", stream=out, quiet=0.0) as lines:
        kernel(10)  # compiles
        for stage in ("reading", "finding"):
            lines.set_postfix_str(stage)
            lines.update()
    said = out.getvalue().splitlines()
    assert [line.split(" (")[0] for line in said] == ["demo: reading", "demo: finding"]
    assert "compiling the numba kernels, first run only" in said[0] and "compiling" not in said[1]
    fresh_kernel()(1)  # after the lines closed: not heard
    assert lines.compile_seconds > 0 and len(out.getvalue().splitlines()) == 2


def test_a_duration_reads_as_a_person_says_it():
    from labrig.progress import duration

    assert [duration(s) for s in (0.5, 45, 89.6, 600, 5399, 12600, 3 * 86400)] == \
        ["0.5 s", "45 s", "90 s", "10 min", "90 min", "3.5 h", "3.0 days"]
