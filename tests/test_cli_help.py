"""The command lines help a user who typed something wrong: "did you mean", errors that point to the subcommand's
help, values that start with a dash read as values, one-line errors for the attack corpus of paths and names, and
exit statuses that tell a crash (1) from a Ctrl-C (130)."""

import os
import subprocess
import sys
import textwrap
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from helpers import disc_film_png, one_line_error

from planarize.cli import main as planarize_main
from qdots.cli import main


@pytest.fixture
def picture(tmp_path) -> Path:
    from PIL import Image

    path = tmp_path / "film.png"
    Image.fromarray((np.random.default_rng(0).random((64, 64)) * 255).astype(np.uint8)).save(path)
    return path


@pytest.mark.parametrize("argv, said", [
    (["mesure", "x.png"], "unknown command 'mesure'; did you mean 'measure'? (see 'qdots --help')"),
    (["measure", "--scalebar", "5nm", "x.png"], "unknown option '--scalebar'; did you mean '--scale-bar'? "
                                                "(see 'qdots measure --help')"),
    (["measure", "--scale_bar", "5nm", "x.png"], "did you mean '--scale-bar'? (see 'qdots measure --help')"),
    (["measure", "x.png", "y.png"], "unrecognized arguments: y.png (see 'qdots measure --help')"),
    (["demo", "--name", "x"], "unknown option '--name' (see 'qdots demo --help')"),
    (["analyze", "s.npz", "--forster-radius", "-inf"], "argument --forster-radius: must be in"),
    (["measure", "--scale-bar", "--polarity", "dark", "x.png"], "--scale-bar: expected one argument"),
])
def test_mistyped_commands_and_options_get_a_suggestion_and_the_right_help(argv, said, capsys, tmp_path,
                                                                            monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    assert said in one_line_error(capsys)


def test_a_value_that_starts_with_a_dash_is_checked_as_a_value(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert planarize_main(["run", "x.toml", "--rtol", "-inf"]) == 2
    assert "argument --rtol: must be in [0.0001, 1], got -inf" in one_line_error(capsys, "planarize")
    assert main(["measure", "x.png", "--scale-bar", "-5nm"]) == 2  # the bar's own check, not "expected one argument"
    assert "expected one argument" not in one_line_error(capsys)


@pytest.mark.parametrize(("option", "declared", "value"), [
    ("--rtol", ("engines", "rtol"), "1.5"), ("--k-exp", ("model", "k_exp"), "7"), ("--step", ("model", "step"), "2e3"),
])
def test_planarize_options_take_their_bounds_and_help_from_the_declarations(option, declared, value, capsys, tmp_path,
                                                                            monkeypatch):
    """An option and the file key it stands for accept the same values and say so in the same words (issue 64,
    item 3: the command line's bounds were written out by hand, and --k-exp took 7 that the model refuses)."""
    from planarize.engines import PARAMS
    from planarize.model import Model

    param = PARAMS["continuum"]["rtol"] if declared[0] == "engines" else Model.PARAMS[declared[1]]
    monkeypatch.chdir(tmp_path)
    argv = ["run", "x.toml", option, value] if option == "--rtol" else ["import", "x.xyz", "--thickness", "1",
                                                                          option, value]
    assert planarize_main(argv) == 2
    said = one_line_error(capsys, "planarize")
    assert f"argument {option}: must be {param.bounds()}" in said and f"got {float(value)!r}" in said
    assert planarize_main([argv[0], "--help"]) == 0
    assert " ".join(param.bounds().split()) in " ".join(capsys.readouterr().out.split())


def test_pictures_that_cannot_be_read_are_refused_at_once(picture, capsys, tmp_path):
    loop = tmp_path / "loop.png"
    os.symlink(loop, loop)
    assert main(["measure", str(loop)]) == 2
    assert "cannot be opened" in one_line_error(capsys)
    odd = tmp_path / "film.xyz"
    odd.write_bytes(picture.read_bytes())  # a PNG under a suffix qdots does not read: refused, as planarize does
    assert main(["measure", str(odd)]) == 2
    assert "the suffix '.xyz' is no picture format qdots reads" in one_line_error(capsys)


@pytest.mark.parametrize("name", ["", "   ", "//"])
def test_a_name_that_leaves_no_file_name_is_refused_not_replaced(picture, name, capsys, tmp_path):
    assert main(["measure", str(picture), "--name", name, "--out", str(tmp_path / "out")]) == 2
    assert "leaves no file name" in one_line_error(capsys)
    assert not (tmp_path / "out").exists()


def test_an_out_folder_that_a_file_is_in_the_way_of_is_said_to_be(picture, capsys, tmp_path):
    blocker = tmp_path / "afile"
    blocker.write_text("mine")
    for out in (blocker, blocker / "sub"):
        assert main(["measure", str(picture), "--out", str(out)]) == 2
        assert "is a file, not a directory" in one_line_error(capsys)
    assert main(["demo", "--out", str(blocker), "--dots", "5", "--seconds", "0.1", "--no-movie"]) == 2
    assert "is a file, not a directory" in one_line_error(capsys) and blocker.read_text() == "mine"


def test_an_absurd_run_length_is_said_in_a_short_line(capsys):
    assert main(["demo", "--seconds", "1e300", "--no-movie"]) == 2
    err = one_line_error(capsys)
    assert "5e+301 steps, more than the 1,000,000,000 one run may take" in err and len(err) < 160


@pytest.fixture
def saved_run(tmp_path) -> Path:
    import qdots
    from qdots.io import checkpoint

    scene = qdots.Scene(box=(100, 100), positions=[(30.0, 30.0), (70.0, 70.0)], radii=[5.0, 5.0])
    sim = qdots.Simulation(scene, [], seed=1)
    sim.run(0.1)
    folder = tmp_path / "runs" / "film"
    folder.mkdir(parents=True)
    checkpoint.save(sim, folder / "film.npz")
    return folder / "film.npz"


def test_resume_refuses_to_write_into_the_runs_own_folder(saved_run, capsys):
    before = sorted(p.name for p in saved_run.parent.iterdir())
    for out in (saved_run.parent, saved_run.parent / "sub"):
        assert main(["resume", str(saved_run), "--seconds", "0.1", "--out", str(out)]) == 2
        assert "is in the folder of the run 'film' itself" in one_line_error(capsys)
    assert sorted(p.name for p in saved_run.parent.iterdir()) == before
    assert main(["resume", str(saved_run), "--seconds", "1e300"]) == 2  # the length, not a name 300 digits long
    assert "steps, more than" in one_line_error(capsys)


def test_infer_says_the_extra_is_missing_before_any_work(picture, capsys, tmp_path, monkeypatch):
    import qdots.micrograph.choices as choices

    monkeypatch.setattr(choices, "missing_infer_extra", lambda: True)
    monkeypatch.chdir(tmp_path)
    assert main(["infer", str(picture), "--library", str(tmp_path / "library")]) == 2
    assert "needs torch and sbi" in one_line_error(capsys)
    assert not (tmp_path / "library").exists() and not (tmp_path / "qdots-infer").exists()


def test_compare_says_when_a_matched_value_was_capped():
    from qdots.inference.compare import MAX_COVERAGE, table_rows

    table = [{"metric": "coverage", "label": "coverage", "image": 0.747, "simulation": 0.547, "standard_error": 0.002,
              "seeds": 3, "matched": True},
             {"metric": "size_spread", "label": "size spread sigma", "image": 0.1, "simulation": 0.1,
              "standard_error": 0.001, "seeds": 3, "matched": True}]
    rows = dict(table_rows(SimpleNamespace(table=table)))
    assert f"capped at {MAX_COVERAGE:g}" in rows["coverage"]
    assert rows["size spread sigma"].endswith("(set to match)")


def test_robust_colour_limits_are_not_stretched_by_a_few_outliers():
    from qdots.render import robust_size_range, size_range

    d = np.random.default_rng(1).normal(10.6, 1.1, 400)
    d[:4] = [4.0, 25.0, 24.0, 4.5]
    low, high = robust_size_range(d / 2)
    assert 6.5 < low < 8.0 and 13.0 < high < 15.0
    assert size_range(d / 2) == pytest.approx((4.0, 25.0))
    assert robust_size_range([5.0, 5.0, 5.0]) == size_range([5.0, 5.0, 5.0])


def test_planarize_import_caps_a_derived_step_and_says_so(tmp_path, capsys):
    from planarize.cli.commands import import_scene

    path = tmp_path / "tall.npy"
    np.save(path, np.random.default_rng(0).random((8, 8)) * 2e7)
    scene = import_scene(path, thickness=100.0, spacing=1000.0, unit="nm")
    assert scene.run.step == 10.0
    assert "capped at 10 nm" in capsys.readouterr().err


CRASH = textwrap.dedent("""
    import sys, types
    module = types.ModuleType("crashing")
    def main(argv):
        raise {error}
    module.main = main
    sys.modules["crashing"] = module
    from labrig.launch import launch
    sys.exit(launch("crashing", "crashing", [], console=True))
""")


@pytest.mark.parametrize("error, status, last", [
    ("RuntimeError('a bug')", 1, "RuntimeError: a bug"),
    ("KeyboardInterrupt()", 130, "crashing: interrupted"),
])
def test_a_crash_exits_1_with_its_traceback_and_a_ctrl_c_130_with_one_line(error, status, last):
    done = subprocess.run([sys.executable, "-c", CRASH.format(error=error)], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == status, done.stderr
    assert done.stderr.strip().splitlines()[-1] == last
    assert ("Traceback" in done.stderr) == (status == 1)


def test_measure_in_a_pipe_says_its_stages_once_it_runs_long(capsys, tmp_path, monkeypatch):
    import labrig.progress

    disc_film_png(tmp_path / "film.png", n=40, size=160)
    monkeypatch.setattr(labrig.progress, "QUIET", 0.0)  # as if every stage came after the first seconds
    assert main(["measure", str(tmp_path / "film.png"), "--nm-per-px", "1", "--no-lqe", "--out",
                 str(tmp_path / "out")]) == 0
    said = capsys.readouterr().err.splitlines()
    assert said and all(line.startswith("qdots measure: ") for line in said)
    assert any(line.startswith("qdots measure: finding the dots (") for line in said)


def test_qdots_demo_sigma_is_the_deposition_s_declaration(capsys, tmp_path, monkeypatch):
    from qdots.experiment import Deposition

    sigma = Deposition.PARAMS["sigma"]
    monkeypatch.chdir(tmp_path)
    assert main(["demo", "--sigma", "1"]) == 2
    assert f"argument --sigma: must be {sigma.bounds()}, got 1.0" in one_line_error(capsys)
    assert main(["demo", "--help"]) == 0
    assert " ".join(sigma.comment().split()) in " ".join(capsys.readouterr().out.split())


def test_measure_says_when_it_looks_at_the_other_polarity(capsys, tmp_path, monkeypatch):
    import labrig.progress
    import qdots.micrograph.measure

    disc_film_png(tmp_path / "film.png", n=40, size=160)
    monkeypatch.setattr(labrig.progress, "QUIET", 0.0)
    # every detection refused: the other polarity and every retry run, each saying so
    monkeypatch.setattr(qdots.micrograph.measure, "film_verdict", lambda detection, *rest: (["refused here"], []))
    assert main(["measure", str(tmp_path / "film.png"), "--nm-per-px", "1", "--no-lqe", "--out",
                 str(tmp_path / "out")]) == 2
    said = capsys.readouterr().err.splitlines()
    other = [i for i, line in enumerate(said) if "objects (the dark ones are not a film of round particles)" in line]
    assert other and said[other[0]].startswith("qdots measure: the light objects")
    assert any("smoothing by" in line for line in said[other[0]:])
