"""What the command lines write, under kills, Ctrl-C and concurrent runs.

An output set is a folder switched into place in one step: a kill at any step of a switch leaves the earlier
set or the new one, byte for byte (every step tried, for qdots and planarize); a second writer of a set is
refused, concurrent runs never lose each other's summary rows, a resume never changes its input, and Ctrl-C
is one line at any moment. A run that fails late leaves the earlier set whole, the input file is never
written over, and stale temporaries and staging directories are cleared.
"""

import csv
import importlib.metadata
import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
from helpers import gravity_scene_file, one_line_error, run_ok

import labrig.staging as staging
import qdots
from labrig.cli import Parser, run_main
from labrig.files import SetBusyError, recover_beside
from labrig.outputset import OutputSet
from labrig.staging import PREFIX
from planarize.cli import main as planarize_main
from planarize.io.results import load_run
from qdots.cli import main as qdots_main
from qdots.cli.commands import OVERLAP_COLUMN, merge_summary

#: Longest any subprocess of these tests may take, s.
TIMEOUT = 300

#: The files of a set like `qdots run --movie --gsd`'s (npz, png, mp4, gsd, toml, ...).
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
    """Every file under ``directory``, by path relative to it (hidden staging directories left out)."""
    return {str(p.relative_to(directory)): p.read_bytes() for p in sorted(directory.rglob("*"))
            if p.is_file() and not any(part.startswith(PREFIX) for part in p.relative_to(directory).parts)}


def write_set(directory: Path, text: str) -> OutputSet:
    with OutputSet(directory, "r") as files:
        for name in NAMES:
            files.stage(name).write_text(f"{text} {name}")
    return files


def versions(directory: Path) -> list[str]:
    return [(directory / "r" / name).read_text().split()[0] for name in NAMES]


def one_line(err: str, prog: str = "qdots") -> str:
    lines = [line for line in err.replace("\r", "\n").splitlines() if line.strip()]
    assert "Traceback" not in err, err
    return lines[-1]


# -- a set switches in one step ------------------------------------------------------------------------

def killed_at_every_step(out: Path, name: str, prog: str, *argv) -> list[dict]:
    """`kill_points.py`: the command killed at each step of its switch in turn, and what each kill left."""
    # run through runpy, not as a script: a script's folder (tests/) comes first on sys.path, where the folders
    # tests/labrig, tests/qdots and tests/planarize would be found as empty namespace packages before the packages
    script = "import runpy, sys; sys.argv = sys.argv[1:]; runpy.run_path(sys.argv[0], run_name='__main__')"
    result = subprocess.run([sys.executable, "-c", script, str(Path(__file__).with_name("kill_points.py")), str(out),
                             name, prog, *map(str, argv)], capture_output=True, text=True, timeout=TIMEOUT)
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)


def check_every_step(results: list[dict], table: bool) -> None:
    *kills, last = results
    assert last["status"] == 0 and not last["killed"] and last["set"] == "new"  # ran past the last step
    assert len(kills) >= 5 and all(r["killed"] for r in kills)
    assert all(r["set"] in ("old", "new") for r in results), results  # never a mix of the two, at any step
    assert kills[0]["set"] == "old" and kills[-1]["set"] == "new"
    if table:
        assert all(r["table"] in ("old", "new") for r in results) and last["table"] == "new"


def test_a_qdots_run_killed_at_any_step_of_its_switch_leaves_the_old_set_or_the_new_one(tmp_path, capsys):
    scene, out = gravity_scene_file(tmp_path), tmp_path / "out"
    run_ok(qdots_main, ["run", str(scene), "--out", str(out), "--movie", "--gsd", "--seed", "1"], capsys)
    results = killed_at_every_step(out, "grav", "qdots", "run", scene, "--out", out, "--movie", "--gsd", "--seed", 2)
    check_every_step(results, table=True)
    assert all(r["visible"] == ["grav", "summary.csv"] for r in results)


@pytest.mark.slow
def test_a_planarize_run_killed_at_any_step_of_its_switch_leaves_the_old_set_or_the_new_one(tmp_path, capsys):
    out = tmp_path / "out"
    run_ok(planarize_main, ["scene", "hill", "--quick", "0.25", "--out", str(out), "--movie"], capsys)
    results = killed_at_every_step(out, "hill_quick_0.25", "planarize", "scene", "hill", "--quick", "0.25",
                                   "--engine", "reference", "--out", out)
    check_every_step(results, table=False)
    assert all(r["visible"] == ["hill_quick_0.25"] for r in results)


def test_the_switch_is_one_exchange_and_a_kill_before_or_after_it_is_cleared_by_the_next_open(tmp_path):
    write_set(tmp_path, "old")
    killed = python("""
        import os, sys
        import labrig.staging as staging
        from labrig.outputset import OutputSet
        exchange = staging.exchange

        def killed_after(a, b):
            exchange(a, b)
            os.kill(os.getpid(), signal.SIGKILL)

        staging.exchange = killed_after
        with OutputSet(sys.argv[1], "r") as files:
            for k in range(9):
                files.stage(f"r.{k}").write_text(f"new r.{k}")
        """, tmp_path)
    assert killed.returncode == -signal.SIGKILL
    assert versions(tmp_path) == ["new"] * len(NAMES)
    (left,) = stagings(tmp_path)  # the earlier set, hidden, its process gone
    assert sorted(os.listdir(tmp_path / left)) == NAMES
    recover_beside(tmp_path / "r" / "r.0")  # a reader clears it
    assert stagings(tmp_path) == [] and versions(tmp_path) == ["new"] * len(NAMES)


def test_without_an_exchange_a_switch_cut_between_its_two_renames_is_rolled_forward(tmp_path, monkeypatch):
    write_set(tmp_path, "old")
    killed = python("""
        import errno, os, sys
        import labrig.staging as staging
        from labrig.outputset import OutputSet

        def unsupported(a, b):
            raise staging.ExchangeUnsupported(errno.EINVAL, "no exchange on this filesystem")

        rename = os.rename
        def killed_after_the_first(source, target):
            rename(source, target)
            if str(target).endswith(".old"):
                os.kill(os.getpid(), signal.SIGKILL)

        staging.exchange, os.rename = unsupported, killed_after_the_first
        with OutputSet(sys.argv[1], "r") as files:
            for k in range(9):
                files.stage(f"r.{k}").write_text(f"new r.{k}")
        """, tmp_path)
    assert killed.returncode == -signal.SIGKILL
    assert not (tmp_path / "r").exists() and len(stagings(tmp_path)) == 2  # the new set and the old, aside
    OutputSet(tmp_path, "another").abort()  # the next open rolls the switch forward
    assert versions(tmp_path) == ["new"] * len(NAMES) and stagings(tmp_path) == []
    # and in this process: without the exchange, the two renames switch the set
    monkeypatch.setattr(staging, "exchange", lambda a, b: (_ for _ in ()).throw(staging.ExchangeUnsupported(22, "no")))
    write_set(tmp_path, "newer")
    assert versions(tmp_path) == ["newer"] * len(NAMES) and stagings(tmp_path) == []


def test_ctrl_c_during_a_switch_waits_for_it_and_says_the_files_were_written(tmp_path, monkeypatch):
    write_set(tmp_path, "old")
    exchange = staging.exchange

    def interrupted(a, b):
        os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C as the switch runs
        exchange(a, b)

    monkeypatch.setattr(staging, "exchange", interrupted)
    with pytest.raises(KeyboardInterrupt, match="the files of r were written"):
        write_set(tmp_path, "new")
    assert versions(tmp_path) == ["new"] * len(NAMES) and stagings(tmp_path) == []


def test_sigkill_before_the_switch_leaves_the_earlier_set_and_the_next_open_clears_it(tmp_path):
    write_set(tmp_path, "old")
    killed = python("""
        import os, sys
        from labrig.outputset import OutputSet
        with OutputSet(sys.argv[1], "r") as files:
            for k in range(9):
                files.stage(f"r.{k}").write_text(f"new r.{k}")
            os.kill(os.getpid(), signal.SIGKILL)
        """, tmp_path)
    assert killed.returncode == -signal.SIGKILL
    assert versions(tmp_path) == ["old"] * len(NAMES) and len(stagings(tmp_path)) == 1
    write_set(tmp_path, "newer")
    assert versions(tmp_path) == ["newer"] * len(NAMES) and stagings(tmp_path) == []


def test_earlier_files_a_set_does_not_write_are_carried_over_unless_dropped(tmp_path):
    write_set(tmp_path, "old")
    (tmp_path / "r" / "notes.txt").write_text("a person's notes")
    with OutputSet(tmp_path, "r") as files:
        files.stage("r.0").write_text("new r.0")
        files.drop("r.1")
        files.keep_as("r.2", "r.2.kept")
    assert sorted(os.listdir(tmp_path / "r")) == sorted(["notes.txt", "r.0", "r.2.kept"] + NAMES[3:])
    assert (tmp_path / "r" / "r.2.kept").read_text() == "old r.2" and files.removed == [tmp_path / "r" / "r.1"]
    (tmp_path / "r" / "sub").mkdir()  # a folder cannot be carried over: refused before anything is written
    with pytest.raises(ValueError, match="holds the folder 'sub'"):
        OutputSet(tmp_path, "r")
    (tmp_path / "f").write_text("a file where the set's folder goes")
    with pytest.raises(ValueError, match="is a file"):
        OutputSet(tmp_path, "f")


def test_a_name_too_long_for_a_file_name_is_a_one_line_error_without_internal_paths(tmp_path, capsys):
    scene = tmp_path / "long.toml"
    scene.write_text(gravity_scene_file(tmp_path).read_text().replace('name = "grav"', f'name = "{"x" * 300}"'))
    assert qdots_main(["run", str(scene), "--out", str(tmp_path / "out")]) == 2
    err = one_line_error(capsys)
    assert "name must be at most 200 characters" in err and "got 300" in err and PREFIX not in err
    assert not (tmp_path / "out").exists()
    hill = tmp_path / "hill.toml"
    run_ok(planarize_main, ["scene", "hill", "--save", str(hill)], capsys)
    hill.write_text(hill.read_text().replace('name = "hill"', f'name = "{"y" * 300}"'))
    assert planarize_main(["run", str(hill), "--out", str(tmp_path / "out")]) == 2
    err = one_line_error(capsys, "planarize")
    assert "name must be at most 200 characters" in err and PREFIX not in err


def test_qdots_run_replaces_its_folder_and_a_reader_never_sees_a_mix(tmp_path, capsys):
    scene, out = gravity_scene_file(tmp_path), tmp_path / "out"
    assert qdots_main(["run", str(scene), "--out", str(out), "--movie", "--gsd", "--seed", "1"]) == 0
    first = contents(out / "grav")
    assert sorted(first) == ["grav.gsd", "grav.mp4", "grav.npz", "grav.png", "grav.toml"]
    assert qdots_main(["run", str(scene), "--out", str(out), "--movie", "--gsd", "--seed", "2"]) == 0
    capsys.readouterr()
    now = contents(out / "grav")
    assert sorted(now) == sorted(first) and all(now[name] != first[name] for name in first)
    (row,) = rows(out / "summary.csv")
    assert row["seed"] == "2" and row["state_file"] == "grav/grav.npz" and stagings(out) == []


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
    run = load_run(out / "hill_quick_0.25" / "hill_quick_0.25.npz")  # the reader clears it
    assert run.complete and contents(out) == before and stagings(out) == []


# -- earlier files survive a later run ---------------------------------------------------------------

def test_a_run_that_fails_late_leaves_the_earlier_files_whole(tmp_path, capsys, monkeypatch):
    scene = gravity_scene_file(tmp_path)
    out = tmp_path / "out"
    run_ok(qdots_main, ["run", str(scene), "--out", str(out)], capsys)
    before = contents(out)

    def fail(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(qdots.render, "save_png", fail)
    assert qdots_main(["run", str(scene), "--out", str(out), "--seed", "9"]) == 2
    one_line_error(capsys)
    assert contents(out) == before and sorted(os.listdir(out)) == ["grav", "summary.csv"]  # nothing replaced or left


def test_the_input_scene_file_is_never_written_over(tmp_path, capsys):
    scene = gravity_scene_file(tmp_path)
    written = scene.read_text()
    run_ok(qdots_main, ["run", str(scene), "--seed", "7", "--out", str(tmp_path)], capsys)
    assert scene.read_text() == written
    run_ok(qdots_main, ["run", str(tmp_path / "grav" / "grav.toml"), "--seed", "8", "--out", str(tmp_path)], capsys)
    assert "seed = 7" in (tmp_path / "grav" / "grav.toml").read_text()  # the input, carried into the new set
    assert "seed = 8" in (tmp_path / "grav" / "grav.ran.toml").read_text()
    out = tmp_path / "out"
    hill = out / "hill_quick_0.25" / "hill_quick_0.25.toml"  # a run's own copy of its scene
    run_ok(planarize_main, ["scene", "hill", "--quick", "0.25", "--out", str(out)], capsys)
    text = hill.read_text()
    run_ok(planarize_main, ["run", str(hill), "--engine", "reference", "--out", str(out)], capsys)
    assert hill.read_text() == text
    assert '[engine]\nkind = "reference"' in (hill.parent / "hill_quick_0.25.ran.toml").read_text()


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
        recover_beside(tmp_path / "r" / "r.0")  # a reader while the set is written
        assert files.staging.is_dir()
        message = f"r in {tmp_path} is being written by another run (pid {os.getpid()}): wait for it or choose"
        with pytest.raises(SetBusyError, match=message.replace("(", r"\(").replace(")", r"\)")):
            OutputSet(tmp_path, "r")
        OutputSet(tmp_path, "r2").abort()  # another set of the same directory is free
        other = python("import sys\nfrom labrig.outputset import OutputSet\nOutputSet(sys.argv[1], 'r')", tmp_path)
        assert "SetBusyError" in other.stderr and f"(pid {os.getpid()})" in other.stderr
    assert (tmp_path / "r" / "r.0").read_text() == "new" and stagings(tmp_path) == []


def test_a_run_or_resume_of_a_set_being_written_is_refused_before_it_starts(tmp_path, capsys):
    scene, out = gravity_scene_file(tmp_path), tmp_path / "out"
    assert qdots_main(["run", str(scene), "--out", str(out)]) == 0
    capsys.readouterr()
    before = contents(out)
    with OutputSet(out, "grav"):
        for argv in (["run", scene, "--out", out],
                     ["resume", out / "grav" / "grav.npz", "--seconds", "1", "--in-place"]):
            result = command("qdots", *argv)
            assert result.returncode == 2
            assert one_line(result.stderr) == (f"qdots: error: grav in {out} is being written by another run "
                                               f"(pid {os.getpid()}): wait for it or choose another --out")
        assert contents(out) == before


def test_concurrent_in_place_resumes_of_one_checkpoint_never_drop_a_continuation(tmp_path, capsys):
    scene, out = gravity_scene_file(tmp_path), tmp_path / "out"
    assert qdots_main(["run", str(scene), "--out", str(out)]) == 0
    capsys.readouterr()
    state = out / "grav" / "grav.npz"
    start = qdots.read_state(state).time
    code = LAUNCH.format(prog="qdots")
    argv = ["resume", str(state), "--seconds", "1", "--in-place"]
    runs = [started(code, *argv) for _ in range(2)]
    results = [waited(run) for run in runs]
    finished = [status for status, _ in results if status == 0]
    for status, err in results:
        assert status == 0 or (status == 2 and "is being written by another run" in one_line(err)), err
    # each continuation that said it finished is in the checkpoint (one refused, or both one after the other)
    assert finished and qdots.read_state(state).time == pytest.approx(start + len(finished))


# -- concurrent runs share a summary -------------------------------------------------------------------

MERGER = """
import sys
from pathlib import Path
from labrig.outputset import OutputSet
from qdots.cli.commands import merge_summary

out, who, n = Path(sys.argv[1]), sys.argv[2], int(sys.argv[3])
for k in range(n):
    row = {"name": f"{who}{k}", "state_file": f"{who}{k}/{who}{k}.npz"}
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


# -- a resume never changes its input ---------------------------------------------------------------------

def test_resume_writes_a_new_set_beside_its_input_and_says_its_name(tmp_path, capsys):
    assert qdots_main(["resume", "--help"]) == 0
    help_text = " ".join(capsys.readouterr().out.split())
    assert "A resume never changes its input" in help_text and "--in-place replaces the run's own folder" in help_text
    scene, out = gravity_scene_file(tmp_path), tmp_path / "out"
    assert qdots_main(["run", str(scene), "--out", str(out), "--movie"]) == 0
    capsys.readouterr()
    earlier = contents(out / "grav")
    assert qdots_main(["resume", str(out / "grav" / "grav.npz"), "--seconds", "1"]) == 0
    printed = capsys.readouterr().out
    assert f"wrote the continuation as the new run grav-t4s in {out / 'grav-t4s'}" in printed
    assert f"{out / 'grav' / 'grav.npz'} is unchanged" in printed
    assert contents(out / "grav") == earlier  # the input, byte for byte
    assert sorted(contents(out / "grav-t4s")) == ["grav-t4s.npz", "grav-t4s.png"]
    assert qdots.read_state(out / "grav-t4s" / "grav-t4s.npz").time == pytest.approx(4.0)
    table = {row["name"]: row for row in rows(out / "summary.csv")}
    assert table["grav-t4s"]["seed"] == "154" and table["grav-t4s"]["resumed_from"] == str(out / "grav" / "grav.npz")
    assert float(table["grav"]["time_s"]) == pytest.approx(3.0)  # the input's row, as it was
    # a continuation of the continuation, into another directory
    assert qdots_main(["resume", str(out / "grav-t4s" / "grav-t4s.npz"), "--seconds", "1", "--out",
                       str(tmp_path / "more")]) == 0
    assert qdots.read_state(tmp_path / "more" / "grav-t5s" / "grav-t5s.npz").time == pytest.approx(5.0)
    # --in-place needs the run's own folder
    loose = tmp_path / "loose.npz"
    loose.write_bytes((out / "grav" / "grav.npz").read_bytes())
    assert qdots_main(["resume", str(loose), "--seconds", "1", "--in-place"]) == 2
    assert "not in a folder of its name" in one_line_error(capsys)
    assert qdots_main(["resume", str(loose), "--seconds", "1"]) == 0  # beside it: loose-t4s/
    assert (tmp_path / "loose-t4s" / "loose-t4s.npz").exists() and loose.exists()


def test_resume_in_place_keeps_the_earlier_movie_under_a_name_that_says_what_it_shows(tmp_path, capsys):
    scene, out = gravity_scene_file(tmp_path), tmp_path / "out"
    assert qdots_main(["run", str(scene), "--out", str(out), "--movie", "--gsd"]) == 0
    capsys.readouterr()
    earlier = contents(out / "grav")
    state = out / "grav" / "grav.npz"
    assert qdots_main(["resume", str(state), "--seconds", "1", "--in-place"]) == 0
    printed = capsys.readouterr().out
    assert "kept the earlier grav.mp4 as grav.until-3s.mp4 (it shows the run up to 3 s)" in printed
    assert "kept the earlier grav.gsd as grav.until-3s.gsd" in printed
    now = contents(out / "grav")
    assert sorted(now) == ["grav.npz", "grav.png", "grav.toml", "grav.until-3s.gsd", "grav.until-3s.mp4"]
    assert now["grav.until-3s.mp4"] == earlier["grav.mp4"] and now["grav.until-3s.gsd"] == earlier["grav.gsd"]
    assert now["grav.png"] != earlier["grav.png"] and qdots.read_state(state).time == pytest.approx(4.0)
    (row,) = rows(out / "summary.csv")
    assert float(row["time_s"]) == pytest.approx(4.0) and row["seed"] == "154"  # its parameters kept
    # with --movie: the new movie shows the continuation, the one before is kept beside it
    assert qdots_main(["resume", str(state), "--seconds", "1", "--movie", "--in-place"]) == 0
    assert "grav.until-3s.mp4" in os.listdir(out / "grav") and "grav.mp4" in os.listdir(out / "grav")
    assert "grav.until-4s.mp4" not in os.listdir(out / "grav")  # there was no movie up to 4 s
    # a new run replaces the whole set: the movies of the run it replaces go with it
    assert qdots_main(["run", str(scene), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "removed the earlier grav.mp4" in printed and "removed the earlier grav.until-3s.mp4" in printed
    assert sorted(os.listdir(out / "grav")) == ["grav.npz", "grav.png", "grav.toml"]
    (row,) = rows(out / "summary.csv")
    assert row.get("resumed_from", "") == "" and float(row["time_s"]) == pytest.approx(3.0)


def test_render_says_that_it_replaced_the_runs_picture(tmp_path, capsys):
    scene, out = gravity_scene_file(tmp_path), tmp_path / "out"
    assert qdots_main(["run", str(scene), "--out", str(out)]) == 0
    capsys.readouterr()
    assert qdots_main(["render", str(out / "grav" / "grav.npz")]) == 0
    assert "replaced the earlier picture" in capsys.readouterr().out
    assert qdots_main(["render", str(out / "grav" / "grav.npz"), "--out", str(tmp_path / "new.png")]) == 0
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


def test_planarize_interrupted_mid_run_says_so_on_its_own_line(tmp_path, capsys, monkeypatch):
    from planarize.engines.continuum import ContinuumEngine

    advance, calls = ContinuumEngine.advance, [0]

    def interrupted(self, until):
        calls[0] += 1
        if calls[0] == 10:
            raise KeyboardInterrupt  # Ctrl-C while the progress bar is on its line
        advance(self, until)

    monkeypatch.setattr(ContinuumEngine, "advance", interrupted)
    assert planarize_main(["scene", "hill", "--out", str(tmp_path / "out")]) == 130
    err = capsys.readouterr().err
    assert err.endswith("\nplanarize: interrupted\n") and "oxide, grid 1/4 (error estimate):" in err  # the bar ended its line first
    assert not (tmp_path / "out").exists()


FINISHED = """
import os, signal, sys, time, types, atexit
module = types.ModuleType("finished_cli")

class Teardown:
    def __del__(self):  # runs as Python tears its modules down, if it does
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.2)

def main(argv):
    module.kept = Teardown()
    if argv == ["during-exit-handlers"]:
        atexit.register(lambda: (os.kill(os.getpid(), signal.SIGINT), time.sleep(0.2)))
    print("results written", flush=True)
    return 0

module.main = main
sys.modules["finished_cli"] = module
from labrig.launch import launch
sys.exit(launch("qdots", "finished_cli", sys.argv[1:], console=True))
"""


@pytest.mark.parametrize("when", ["during-teardown", "during-exit-handlers"])
def test_ctrl_c_after_the_command_finished_is_one_line_or_nothing_never_a_death_by_signal(when):
    result = python(FINISHED, when)
    assert result.stdout == "results written\n"
    if when == "during-teardown":  # the entry point ends the process before Python tears its modules down
        assert result.returncode == 0 and result.stderr == ""
    else:
        assert result.returncode == 130
        assert result.stderr == "qdots: interrupted after it had finished (its results are written)\n"


def test_ctrl_c_while_a_finished_sweep_prints_its_table_says_every_result_was_written(tmp_path, capsys, monkeypatch):
    import labrig.sweeps.command as command

    path = tmp_path / "k.toml"
    path.write_text('[base]\nsurface.kind = "hill"\nsurface.refine = 1\nrun.thickness = 0.3\nrun.step = 0.05\n'
                    '[axes]\n"run.k_exp" = [1.5, 2.0]\n')

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(command, "print_table", interrupted)
    assert planarize_main(["sweep", str(path), "--workers", "1", "--out", str(tmp_path / "k")]) == 130
    err = capsys.readouterr().err.splitlines()[-1]
    assert err == f"planarize: interrupted after every run's result was written ({tmp_path / 'k' / 'table.csv'})"
    assert len(rows(tmp_path / "k" / "table.csv")) == 2


def test_a_ragged_row_of_an_earlier_summary_is_never_lost(tmp_path, capsys):
    scene, out = gravity_scene_file(tmp_path), tmp_path / "out"
    out.mkdir()
    earlier = ("name,seed,state_file\n"
               "kept,1,kept/kept.npz\n"
               "ragged,2,ragged/ragged.npz,an extra cell\n"
               "short,3\n")
    (out / "summary.csv").write_text(earlier)
    assert qdots_main(["run", str(scene), "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert f"warning: {out / 'summary.csv'}: lines 3, 4 have more or fewer cells than the header" in err
    assert f"kept whole as {out / 'summary.csv.ragged'}" in err
    assert (out / "summary.csv.ragged").read_text() == earlier  # the rows it could not read, kept as written
    assert [row["name"] for row in rows(out / "summary.csv")] == ["kept", "grav"]
    assert qdots_main(["run", str(scene), "--out", str(out), "--seed", "3"]) == 0  # a good table: nothing set aside
    assert "warning" not in capsys.readouterr().err and sorted(p.name for p in out.glob("summary.csv*")) == [
        "summary.csv", "summary.csv.ragged"]


def test_the_old_import_of_output_sets_still_works_until_0_4_and_says_so():
    import labrig.files
    import labrig.outputset

    with pytest.warns(DeprecationWarning, match=r"labrig.files.OutputSet is labrig.outputset.OutputSet; .* in 0.4"):
        assert labrig.files.OutputSet is labrig.outputset.OutputSet
    with pytest.raises(AttributeError, match="no attribute 'Nothing'"):
        labrig.files.Nothing  # noqa: B018
