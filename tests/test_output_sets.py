"""What the command lines write, under kills, Ctrl-C and concurrent runs.

An output set switches all at once (a kill between two of its renames is rolled forward by the next
open or reader), a second writer of a set is refused, concurrent runs never lose each other's summary
rows, a resumed run leaves a coherent set, and Ctrl-C is one line at any moment. A run that fails late leaves
the earlier files whole, the input file is never written over, and stale temporaries are cleared.
"""

import csv
import importlib.metadata
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

import qdots
from labrig.cli import Parser, run_main
from labrig.files import OutputSet, SetBusyError, recover_beside
from labrig.staging import JOURNAL, PREFIX
from planarize.cli import main as planarize_main
from planarize.io.results import load_run
from qdots.cli import main as qdots_main
from qdots.cli.commands import OVERLAP_COLUMN, merge_summary

from helpers import gravity_scene_file, one_line_error, run_ok

#: Longest any subprocess of these tests may take, s.
TIMEOUT = 300

#: The files of a set like `qdots run --movie --gsd`'s (npz, png, mp4, gsd, toml, summary, ...): nine renames.
NAMES = [f"r.{k}" for k in range(9)]


def python(code: str, *args, timeout: float = TIMEOUT) -> subprocess.CompletedProcess:
    """Run ``code`` in a fresh interpreter (Ctrl-C raising KeyboardInterrupt, as in a terminal)."""
    prologue = "import signal\nsignal.signal(signal.SIGINT, signal.default_int_handler)\n"
    return subprocess.run([sys.executable, "-c", prologue + textwrap.dedent(code), *map(str, args)],
                          capture_output=True, text=True, timeout=timeout)


#: A command line run through the console entry point (`labrig.launch`).
LAUNCH = """
import sys
from labrig.launch import {prog}
sys.exit({prog}(sys.argv[1:]))
"""


def started(*args) -> subprocess.Popen:
    """A process of ``python -c ARGS...``, to run alongside others (`waited`)."""
    return subprocess.Popen([sys.executable, "-c", *map(str, args)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)


def waited(run: subprocess.Popen) -> tuple[int, str]:
    """The exit status and stderr of ``run``, once it has ended (killed after `TIMEOUT` s)."""
    try:
        _, err = run.communicate(timeout=TIMEOUT)
    except subprocess.TimeoutExpired:
        run.kill()
        run.communicate(timeout=30)
        raise
    return run.returncode, err


def command(prog: str, *args, timeout: float = TIMEOUT) -> subprocess.CompletedProcess:
    return python(LAUNCH.format(prog=prog), *args, timeout=timeout)


def rows(path: Path) -> list[dict]:
    with open(path, newline="") as stream:
        return list(csv.DictReader(stream))


def stagings(directory: Path) -> list[str]:
    return sorted(p.name for p in directory.iterdir() if p.name.startswith(PREFIX))


def contents(directory: Path) -> dict:
    return {p.name: p.read_bytes() for p in directory.iterdir() if p.is_file()}


def write_set(directory: Path, text: str) -> OutputSet:
    with OutputSet(directory, "r") as files:
        for name in NAMES:
            files.stage(name).write_text(f"{text} {name}")
    return files


def versions(directory: Path) -> list[str]:
    return [(directory / name).read_text().split()[0] for name in NAMES]


class FailingRename:
    """``os.replace`` that raises at its ``n``-th rename into ``directory``: a kill between two renames of a
    switch, as the process that was killed sees it."""

    def __init__(self, directory: Path, n: int):
        self.directory, self.n, self.count, self.replace = Path(directory), n, 0, os.replace

    def __call__(self, source, target):
        if Path(target).parent == self.directory:
            self.count += 1
            if self.count == self.n:
                raise OSError("killed between two renames")
        return self.replace(source, target)


def one_line(err: str, prog: str = "qdots") -> str:
    lines = [line for line in err.replace("\r", "\n").splitlines() if line.strip()]
    assert "Traceback" not in err, err
    return lines[-1]


# -- a set switches at once --------------------------------------------------------------------------

@pytest.mark.parametrize("n", range(2, len(NAMES) + 1))
@pytest.mark.parametrize("recovered_by", ["reader", "next set"])
def test_a_switch_cut_between_two_renames_is_rolled_forward(tmp_path, monkeypatch, n, recovered_by):
    write_set(tmp_path, "old")
    monkeypatch.setattr(os, "replace", FailingRename(tmp_path, n))
    with pytest.raises(OSError, match="killed between two renames"):
        write_set(tmp_path, "new")
    monkeypatch.undo()
    assert versions(tmp_path) == ["new"] * (n - 1) + ["old"] * (len(NAMES) - n + 1)  # what the kill left
    (staging,) = stagings(tmp_path)
    assert (tmp_path / staging / JOURNAL).exists()
    if recovered_by == "reader":
        recover_beside(tmp_path / "r.0")
    else:
        OutputSet(tmp_path, "another").abort()
    assert versions(tmp_path) == ["new"] * len(NAMES) and stagings(tmp_path) == []


def test_ctrl_c_between_two_renames_finishes_the_switch_before_it_stops(tmp_path, monkeypatch):
    write_set(tmp_path, "old")
    replace = os.replace

    def interrupted_once(source, target):
        if Path(target).parent == tmp_path and Path(target).name == "r.4":
            monkeypatch.setattr(os, "replace", replace)
            raise KeyboardInterrupt
        return replace(source, target)

    monkeypatch.setattr(os, "replace", interrupted_once)
    with pytest.raises(KeyboardInterrupt):
        write_set(tmp_path, "new")
    assert versions(tmp_path) == ["new"] * len(NAMES) and stagings(tmp_path) == []


KILLED_SWITCH = """
import os, sys
from pathlib import Path
from labrig.files import OutputSet

out, n = Path(sys.argv[1]), int(sys.argv[2])
replace, count = os.replace, [0]

def killing_replace(source, target):
    if Path(target).parent == out:
        count[0] += 1
        if count[0] == n:
            os.kill(os.getpid(), signal.SIGKILL)
    return replace(source, target)

os.replace = killing_replace
with OutputSet(out, "r") as files:
    for k in range(9):
        files.stage(f"r.{k}").write_text(f"new r.{k}")
    if n == 0:  # killed before the switch
        os.kill(os.getpid(), signal.SIGKILL)
"""


@pytest.mark.parametrize("n", [3, 9])
def test_sigkill_between_the_renames_then_the_next_reader_finishes_the_switch(tmp_path, n):
    write_set(tmp_path, "old")
    assert python(KILLED_SWITCH, tmp_path, n).returncode == -signal.SIGKILL
    assert versions(tmp_path) == ["new"] * (n - 1) + ["old"] * (len(NAMES) - n + 1)
    recover_beside(tmp_path / "r.0")
    assert versions(tmp_path) == ["new"] * len(NAMES) and stagings(tmp_path) == []


def test_sigkill_before_the_switch_leaves_the_earlier_set_and_the_next_open_clears_it(tmp_path):
    write_set(tmp_path, "old")
    assert python(KILLED_SWITCH, tmp_path, 0).returncode == -signal.SIGKILL
    assert versions(tmp_path) == ["old"] * len(NAMES)
    (staging,) = stagings(tmp_path)
    assert not (tmp_path / staging / JOURNAL).exists()
    write_set(tmp_path, "newer")
    assert versions(tmp_path) == ["newer"] * len(NAMES) and stagings(tmp_path) == []


def test_qdots_run_cut_mid_switch_is_finished_by_reading_its_state(tmp_path, capsys, monkeypatch):
    scene, out = gravity_scene_file(tmp_path), tmp_path / "out"
    assert qdots_main(["run", str(scene), "--out", str(out), "--movie", "--gsd", "--seed", "1"]) == 0
    first = contents(out)
    monkeypatch.setattr(os, "replace", FailingRename(out, 5))
    assert qdots_main(["run", str(scene), "--out", str(out), "--movie", "--gsd", "--seed", "2"]) == 2
    monkeypatch.undo()
    capsys.readouterr()
    mixed = contents(out)
    assert any(mixed[name] == first[name] for name in first) and any(mixed[name] != first[name] for name in first)
    qdots.read_state(out / "grav.npz")  # a reader finishes the switch first
    now = contents(out)
    assert sorted(now) == sorted(first) and all(now[name] != first[name] for name in first)
    (row,) = rows(out / "summary.csv")
    assert row["seed"] == "2" and stagings(out) == []


def test_a_killed_planarize_run_leaves_the_earlier_result_alone_and_no_temporary_beside_it(tmp_path, capsys):
    out = tmp_path / "out"
    assert planarize_main(["scene", "hill", "--quick", "0.25", "--out", str(out)]) == 0
    capsys.readouterr()
    before = contents(out)
    killed = python("""
        import os, sys
        import planarize.render as render
        save_figure = render.save_figure

        def killed_after_one_figure(*args, **kwargs):
            save_figure(*args, **kwargs)
            os.kill(os.getpid(), signal.SIGKILL)

        render.save_figure = killed_after_one_figure
        from labrig.launch import planarize
        sys.exit(planarize(sys.argv[1:]))
        """, "scene", "hill", "--quick", "0.25", "--out", out)
    assert killed.returncode == -signal.SIGKILL
    assert contents(out) == before and len(stagings(out)) == 1  # its partial files are in its staging directory
    run = load_run(out / "hill_quick_0.25.npz")  # the reader clears it
    assert run.complete and contents(out) == before and stagings(out) == []


# -- earlier files survive a later run ---------------------------------------------------------------

def test_a_run_that_fails_late_leaves_the_earlier_files_whole(tmp_path, capsys, monkeypatch):
    scene = gravity_scene_file(tmp_path)
    out = tmp_path / "out"
    run_ok(qdots_main, ["run", str(scene), "--out", str(out)], capsys)
    before = {p.name: p.read_bytes() for p in out.iterdir()}

    def fail(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(qdots.render, "save_png", fail)
    assert qdots_main(["run", str(scene), "--out", str(out), "--seed", "9"]) == 2
    one_line_error(capsys)
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before  # nothing replaced, no temporary left


def test_the_input_scene_file_is_never_written_over(tmp_path, capsys):
    scene = gravity_scene_file(tmp_path)
    written = scene.read_text()
    run_ok(qdots_main, ["run", str(scene), "--seed", "7", "--out", str(tmp_path)], capsys)
    assert scene.read_text() == written
    assert "seed = 7" in (tmp_path / "grav.ran.toml").read_text()
    hill = tmp_path / "hill_quick_0.25.toml"  # the name of the scene inside
    run_ok(planarize_main, ["scene", "hill", "--quick", "0.25", "--save", str(hill)], capsys)
    text = hill.read_text()
    run_ok(planarize_main, ["run", str(hill), "--engine", "reference", "--out", str(tmp_path)], capsys)
    assert hill.read_text() == text
    assert 'engine = "reference"' in (tmp_path / "hill_quick_0.25.ran.toml").read_text()


def test_stale_temporary_files_are_cleared_by_the_next_run(tmp_path, capsys):
    scene = gravity_scene_file(tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    stale, fresh = out / ".grav-0123abcd.tmp.npz", out / ".grav-4567cdef.tmp.npz"
    stale.write_bytes(b"partial")
    fresh.write_bytes(b"another run, still writing")
    old = time.time() - 2 * 3600
    os.utime(stale, (old, old))
    run_ok(qdots_main, ["run", str(scene), "--out", str(out)], capsys)
    assert not stale.exists() and fresh.exists()


# -- one writer per set ------------------------------------------------------------------------------

def test_a_live_set_is_left_alone_and_a_second_writer_is_refused(tmp_path):
    with OutputSet(tmp_path, "r") as files:
        files.stage("r.0").write_text("new")
        recover_beside(tmp_path / "r.0")  # a reader while the set is written
        assert files.staging.is_dir()
        message = f"r in {tmp_path} is being written by another run (pid {os.getpid()}): wait for it or choose"
        with pytest.raises(SetBusyError, match=message.replace("(", r"\(").replace(")", r"\)")):
            OutputSet(tmp_path, "r")
        OutputSet(tmp_path, "r2").abort()  # another set of the same directory is free
        other = python("import sys\nfrom labrig.files import OutputSet\nOutputSet(sys.argv[1], 'r')", tmp_path)
        assert "SetBusyError" in other.stderr and f"(pid {os.getpid()})" in other.stderr
    assert (tmp_path / "r.0").read_text() == "new" and stagings(tmp_path) == []


def test_a_run_or_resume_of_a_set_being_written_is_refused_before_it_starts(tmp_path, capsys):
    scene, out = gravity_scene_file(tmp_path), tmp_path / "out"
    assert qdots_main(["run", str(scene), "--out", str(out)]) == 0
    capsys.readouterr()
    before = contents(out)
    with OutputSet(out, "grav"):
        for argv in (["run", scene, "--out", out], ["resume", out / "grav.npz", "--seconds", "1"]):
            result = command("qdots", *argv)
            assert result.returncode == 2
            assert one_line(result.stderr) == (f"qdots: error: grav in {out} is being written by another run "
                                               f"(pid {os.getpid()}): wait for it or choose another --out")
        assert contents(out) == before


def test_concurrent_resumes_of_one_checkpoint_never_drop_a_continuation(tmp_path, capsys):
    scene, out = gravity_scene_file(tmp_path), tmp_path / "out"
    assert qdots_main(["run", str(scene), "--out", str(out)]) == 0
    capsys.readouterr()
    start = qdots.read_state(out / "grav.npz").time
    code = LAUNCH.format(prog="qdots")
    argv = ["resume", str(out / "grav.npz"), "--seconds", "1"]
    runs = [started(code, *argv) for _ in range(2)]
    results = [waited(run) for run in runs]
    finished = [status for status, _ in results if status == 0]
    for status, err in results:
        assert status == 0 or (status == 2 and "is being written by another run" in one_line(err)), err
    # each continuation that said it finished is in the checkpoint (one refused, or both one after the other)
    assert finished and qdots.read_state(out / "grav.npz").time == pytest.approx(start + len(finished))


# -- concurrent runs share a summary -------------------------------------------------------------------

MERGER = """
import sys
from pathlib import Path
from labrig.files import OutputSet
from qdots.cli.commands import merge_summary

out, who, n = Path(sys.argv[1]), sys.argv[2], int(sys.argv[3])
for k in range(n):
    row = {"name": f"{who}{k}", "state_file": f"{who}{k}.npz"}
    with OutputSet(out, f"{who}{k}") as files:
        files.stage(f"{who}{k}.npz").write_text("board")
        files.update("summary.csv", lambda current, staged: merge_summary(current, [row], staged))
"""


def test_concurrent_sets_never_lose_a_summary_row(tmp_path):
    writers = ["a", "b", "c"]
    runs = [started(MERGER, tmp_path, who, 40) for who in writers]
    for run in runs:
        status, err = waited(run)
        assert status == 0, err
    names = sorted(row["name"] for row in rows(tmp_path / "summary.csv"))
    assert names == sorted(f"{who}{k}" for who in writers for k in range(40))


def test_two_qdots_runs_of_different_names_into_one_directory_keep_both_rows(tmp_path):
    out = tmp_path / "out"
    scenes = [gravity_scene_file(tmp_path, name) for name in ("first", "second")]
    code = LAUNCH.format(prog="qdots")
    runs = [started(code, "run", scene, "--out", out) for scene in scenes]
    for run in runs:
        status, err = waited(run)
        assert status == 0, err
    assert sorted(row["name"] for row in rows(out / "summary.csv")) == ["first", "second"]


# -- a resumed run writes a coherent set ----------------------------------------------------------------

def test_resume_in_place_keeps_the_earlier_movie_under_a_name_that_says_what_it_shows(tmp_path, capsys):
    scene, out = gravity_scene_file(tmp_path), tmp_path / "out"
    assert qdots_main(["run", str(scene), "--out", str(out), "--movie", "--gsd"]) == 0
    capsys.readouterr()
    earlier = contents(out)
    assert qdots_main(["resume", str(out / "grav.npz"), "--seconds", "1"]) == 0
    printed = capsys.readouterr().out
    assert "kept the earlier grav.mp4 as grav.until-3s.mp4 (it shows the run up to 3 s)" in printed
    assert "kept the earlier grav.gsd as grav.until-3s.gsd" in printed
    now = contents(out)
    assert sorted(now) == ["grav.npz", "grav.png", "grav.toml", "grav.until-3s.gsd", "grav.until-3s.mp4",
                           "summary.csv"]
    assert now["grav.until-3s.mp4"] == earlier["grav.mp4"] and now["grav.until-3s.gsd"] == earlier["grav.gsd"]
    assert now["grav.png"] != earlier["grav.png"] and qdots.read_state(out / "grav.npz").time == pytest.approx(4.0)
    (row,) = rows(out / "summary.csv")
    assert float(row["time_s"]) == pytest.approx(4.0) and row["seed"] == "154"  # its parameters kept
    # with --movie: the new movie shows the continuation, the one before is kept beside it
    assert qdots_main(["resume", str(out / "grav.npz"), "--seconds", "1", "--movie"]) == 0
    assert "grav.until-3s.mp4" in os.listdir(out) and "grav.mp4" in os.listdir(out)
    assert "grav.until-4s.mp4" not in os.listdir(out)  # there was no movie up to 4 s
    # a new run replaces the whole set: the movies of the run it replaces go with it
    assert qdots_main(["run", str(scene), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "removed the earlier grav.mp4" in printed and "removed the earlier grav.until-3s.mp4" in printed
    assert sorted(os.listdir(out)) == ["grav.npz", "grav.png", "grav.toml", "summary.csv"]
    (row,) = rows(out / "summary.csv")
    assert row.get("resumed_from", "") == "" and float(row["time_s"]) == pytest.approx(3.0)


def test_render_says_that_it_replaced_the_runs_picture(tmp_path, capsys):
    scene, out = gravity_scene_file(tmp_path), tmp_path / "out"
    assert qdots_main(["run", str(scene), "--out", str(out)]) == 0
    capsys.readouterr()
    assert qdots_main(["render", str(out / "grav.npz")]) == 0
    assert "replaced the earlier picture" in capsys.readouterr().out
    assert qdots_main(["render", str(out / "grav.npz"), "--out", str(tmp_path / "new.png")]) == 0
    assert "replaced" not in capsys.readouterr().out


# -- the overlap column says its unit ---------------------------------------------------------------------

def test_the_summary_overlap_is_in_percent_of_a_radius_and_old_tables_are_converted(tmp_path, capsys):
    table = tmp_path / "summary.csv"
    table.write_text("name,max_overlap,state_file\nold,0.00125,old.npz\n")
    merge_summary(table, [{"name": "new", OVERLAP_COLUMN: 0.5, "state_file": "new.npz"}])
    merged = {row["name"]: row for row in rows(table)}
    assert "max_overlap" not in merged["old"] and float(merged["old"][OVERLAP_COLUMN]) == pytest.approx(0.125)
    assert float(merged["new"][OVERLAP_COLUMN]) == 0.5
    scene = gravity_scene_file(tmp_path)
    assert qdots_main(["run", str(scene), "--out", str(tmp_path / "out")]) == 0
    printed = capsys.readouterr().out
    (row,) = rows(tmp_path / "out" / "summary.csv")
    assert f"{float(row[OVERLAP_COLUMN]):.3f} % of radius" in printed  # the number the terminal prints


# -- Ctrl-C is one line, whenever it comes ------------------------------------------------------------

def test_the_console_commands_are_the_light_launchers():
    scripts = {ep.name: ep.value for ep in importlib.metadata.entry_points(group="console_scripts")}
    assert scripts["qdots"] == "labrig.launch:qdots" and scripts["planarize"] == "labrig.launch:planarize"


@pytest.mark.parametrize("prog, module, argv", [
    ("qdots", "pymunk", ["run", "missing.toml"]),
    ("qdots", "numba", ["sweep", "missing.toml"]),
    ("planarize", "numba", ["scene", "ta", "--quick", "0.25"]),
])
def test_ctrl_c_while_the_command_imports_is_one_line(tmp_path, prog, module, argv):
    result = python(f"""
        import builtins, sys
        real_import = builtins.__import__

        def interrupted_import(name, *args, **kwargs):
            if name == {module!r}:  # Ctrl-C while the command imports its packages
                builtins.__import__ = real_import
                signal.raise_signal(signal.SIGINT)
            return real_import(name, *args, **kwargs)

        builtins.__import__ = interrupted_import
        from labrig.launch import {prog}
        sys.exit({prog}(sys.argv[1:]))
        """, *argv, "--out", tmp_path / "out")
    assert result.returncode == 130, result.stderr
    assert result.stderr == f"{prog}: interrupted\n"


def test_an_error_that_an_interrupt_caused_in_compiled_code_is_an_interruption(capsys):
    def kernel(args):  # what numba raises when Ctrl-C lands in a compiled kernel
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as exc:
            raise SystemError("CPUDispatcher(<function _closest_sets_thesis>) returned a result with an "
                              "exception set") from exc

    parser = Parser(prog="planarize")
    parser.set_defaults(func=kernel)
    assert run_main(parser, []) == 130
    assert capsys.readouterr().err == "planarize: interrupted\n"

    def bug(args):
        raise SystemError("a bug keeps its traceback")

    parser.set_defaults(func=bug)
    with pytest.raises(SystemError, match="a bug"):
        run_main(parser, [])
