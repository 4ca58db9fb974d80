"""planarize run / scene / import: files written, exit codes, one-line errors."""

import csv
import re
import warnings

import numpy as np
import pytest
from helpers import refused_run, run_ok
from movie_probe import assert_playable

import planarize
from planarize.cli import build_parser, main
from planarize.io.results import load_run
from planarize.io.scenefile import load_scene
from planarize.scene import SCENES

FILES = (".toml", ".npz", "_history.csv", "_fig3-8.png", "_fig3-9.png", "_surfaces.png")


@pytest.fixture(scope="module")
def hill_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("hill")
    assert main(["scene", "hill", "--quick", "0.25", "--out", str(out), "--movie"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["hill_quick_0.25"]  # the run's folder
    return out / "hill_quick_0.25"


def test_scene_writes_every_file(hill_run, capsys):
    stem = "hill_quick_0.25"
    names = sorted(p.name for p in hill_run.iterdir())
    assert names == sorted(stem + suffix for suffix in (*FILES, ".mp4"))
    run = load_run(hill_run / f"{stem}.npz")
    assert run.initial.shape == (5, 5) and run.parameters["rtol"] == 0.08 and run.thickness >= 1.0
    # the quick hill, 5 x 5 points, is one pixel wide (pixel curvature 4.5, as noise): no error is stated for it
    assert run.parameters["engine"] == "continuum" and run.parameters["noisy"]
    assert len(run.parameters["not_asymptotic"]) == 4 and np.isnan(run.history["oxide_rms_error_nm"]).all()
    with open(hill_run / f"{stem}_history.csv", newline="") as stream:
        rows = list(csv.DictReader(stream))
    assert [float(r["oxide_rms_nm"]) for r in rows] == pytest.approx(run.history["oxide_rms_nm"].tolist())
    assert len(run.snapshots) == 41  # 40 intervals, ends included: one frame each, 10 frames/s, 600 px
    assert_playable(hill_run / f"{stem}.mp4", frames=41 + 9, fps=10, size_px=600)  # the last held 1 s
    assert load_scene(hill_run / f"{stem}.toml") == SCENES["hill"].quick(0.25)


def test_run_reproduces_the_scene_file_and_overrides_the_engine(hill_run, tmp_path):
    scene = hill_run / "hill_quick_0.25.toml"
    first = load_run(hill_run / "hill_quick_0.25.npz")
    assert main(["run", str(scene), "--out", str(tmp_path)]) == 0
    again = load_run(tmp_path / "hill_quick_0.25" / "hill_quick_0.25.npz")
    assert again.oxide == first.oxide and np.array_equal(again.history["metal_rms_nm"], first.history["metal_rms_nm"])
    assert main(["run", str(scene), "--out", str(tmp_path / "ref"), "--engine", "reference"]) == 0
    reference = load_run(tmp_path / "ref" / "hill_quick_0.25" / "hill_quick_0.25.npz")
    assert reference.parameters["engine"] == "reference" and reference.parameters["step"] == 0.04
    assert main(["run", str(scene), "--out", str(tmp_path / "fast"), "--engine", "fast"]) == 0
    fast = load_run(tmp_path / "fast" / "hill_quick_0.25" / "hill_quick_0.25.npz")
    assert reference.history["oxide_rms_nm"][-1] == pytest.approx(fast.history["oxide_rms_nm"][-1], abs=0.01)
    assert main(["run", str(scene), "--out", str(tmp_path / "loose"), "--rtol", "0.5"]) == 0
    loose = load_run(tmp_path / "loose" / "hill_quick_0.25" / "hill_quick_0.25.npz")
    assert loose.parameters["rtol"] == 0.5 and loose.parameters["refine"] <= first.parameters["refine"]


def test_scene_save_writes_the_named_scene(tmp_path, capsys):
    assert main(["scene", "ta", "--save", str(tmp_path / "ta.toml")]) == 0
    assert load_scene(tmp_path / "ta.toml") == SCENES["ta"]
    assert capsys.readouterr().out.strip() == str(tmp_path / "ta.toml")


def test_import_runs_a_height_map(tmp_path, capsys):
    z = planarize.surfaces.bump(5.0, base=4.0, refine=1).z  # 5 x 5, one raised point
    np.savetxt(tmp_path / "afm.csv", z * 1e-9, delimiter=",")
    out = tmp_path / "out"
    code = main(["import", str(tmp_path / "afm.csv"), "--unit", "m", "--spacing", "1e-9", "--thickness", "0.5",
                 "--out", str(out)])
    assert code == 0
    assert sorted(p.name for p in (out / "afm").iterdir()) == sorted("afm" + s for s in FILES)
    run = load_run(out / "afm" / "afm.npz")
    np.testing.assert_allclose(run.initial.z, z)
    assert load_scene(out / "afm" / "afm.toml").run.step == 0.01  # z-range 1 nm / 100
    assert "metal RMS" in capsys.readouterr().out
    scene = load_scene(out / "afm" / "afm.toml")  # the provenance copy re-runs from anywhere
    assert scene.surface.params["path"] == str((tmp_path / "afm.csv").resolve())
    assert main(["import", str(tmp_path / "afm.csv"), "--unit", "m", "--spacing", "1e-9", "--thickness", "0.5",
                 "--step", "0.1", "--save", str(tmp_path / "s.toml")]) == 0
    assert load_scene(tmp_path / "s.toml").run.step == 0.1


def test_an_empty_snapshot_list_runs_and_writes_its_files(tmp_path, capsys):
    path = tmp_path / "none.toml"
    path.write_text("name = 'none'\n[surface]\nrefine = 1\n[run]\nthickness = 0.2\nsnapshots = []\n")
    run_ok(main, ["run", str(path), "--out", str(tmp_path)], capsys)
    assert (tmp_path / "none" / "none.npz").exists() and not (tmp_path / "none" / "none_surfaces.png").exists()


@pytest.mark.parametrize("argv, match", [
    (["scene", "mountain"], "invalid choice: 'mountain'"),
    (["run", "absent.toml"], "scene file 'absent.toml' does not exist"),
    (["run", "{bad}.toml"], r"bad.toml: unknown key 'run.stpe'"),
    (["scene", "hill", "--quick", "2"], r"argument --quick: must be in \(0, 1\], got 2.0"),
    (["import", "{csv}"], "the following arguments are required: --thickness"),
    (["import", "{csv}", "--thickness", "1"], "does not state the unit"),
    (["import", "{csv}", "--thickness", "1", "--unit", "nm"], "does not state its grid spacing"),
    (["import", "{csv}", "--thickness", "1", "--unit", "parsec", "--spacing", "1"], "unit must be one of 'nm'"),
    (["import", "{csv}", "--thickness", "1", "--unit", "nm", "--spacing", "1", "2", "3"], "--spacing takes DX or DX DY"),
    (["import", "{csv}", "--thickness", "-1", "--unit", "nm", "--spacing", "1"], r"must be >= 0"),
    ([], "the following arguments are required: COMMAND"),
])
def test_bad_input_is_one_line_and_exit_code_2(tmp_path, capsys, argv, match):
    (tmp_path / "bad.toml").write_text("[run]\nstpe = 1\n")
    np.savetxt(tmp_path / "z.csv", np.ones((3, 3)), delimiter=",")
    argv = [a.format(bad=tmp_path / "bad", csv=tmp_path / "z.csv") for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("planarize: error: ") and err.count("\n") == 1
    assert re.search(match, err), err


@pytest.mark.parametrize("run_table, message", [
    ("k_exp = 1e100", r"run.k_exp must be in \[1, 5\]"),
    ("k_exp = 1e10", r"run.k_exp"),
    ("thickness = 0.1\nstep = 5.0", r"step \(5 nm\) must not exceed thickness \(0.1 nm\)"),
    ("record = []", r"run.record"),
    ("thickness = inf", r"run.thickness"),
    ("thickness = 1.0\n[engine]\nkind = 'reference'\ntolerance = 0.1", r"engine.tolerance is a setting of the fast "
                                                                       r"engine, not of engine 'reference'"),
])
def test_planarize_parameters_out_of_range_are_one_line_errors(tmp_path, capsys, run_table, message):
    error = refused_run(main, tmp_path / "bad.toml", f"[run]\n{run_table}\n", capsys, "planarize")
    assert re.search(message, error)


def test_a_scene_file_with_the_engine_in_its_run_table_runs_with_a_one_line_note(tmp_path, capsys):
    path = tmp_path / "old.toml"
    path.write_text("name = 'old'\n[surface]\nrefine = 1\n[run]\nthickness = 0.1\nengine = 'fast'\n")
    with warnings.catch_warnings():  # the suite makes warnings errors; the command shows this one as a note
        warnings.simplefilter("always", FutureWarning)
        assert main(["run", str(path), "--out", str(tmp_path / "out")]) == 0
    notes = [line for line in capsys.readouterr().err.splitlines() if "since 0.3" in line]
    assert notes == [notes[0]] and notes[0].startswith("planarize: note: run.engine: since 0.3 the engine"), notes
    written = (tmp_path / "out" / "old" / "old.toml").read_text()
    assert '[engine]\nkind = "fast"' in written and "\nengine =" not in written


def test_help_and_commands(capsys):
    assert main(["--help"]) == 0
    out = capsys.readouterr().out
    for command in ("run", "scene", "import"):
        assert command in out
    assert main(["--version"]) == 0
    assert [a.dest for a in build_parser()._subparsers._group_actions] == ["command"]
