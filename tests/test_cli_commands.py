"""qdots run / preset / resume / render: files written, boards out of the ordinary (a dot in a wall, dots
overlapping at a coarse step, dots escaped from an open board), exit codes, one-line errors (and the checks of
paths that both command lines share)."""

import csv
import os
import re
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest
from helpers import gravity_scene_file, one_line_error, refused_run, run_ok, to_toml
from movie_probe import probe

import qdots
from planarize.cli import main as planarize_main
from qdots.cli import main


def rows(path):
    with open(path, newline="") as stream:
        return list(csv.DictReader(stream))


@pytest.fixture(scope="module")
def preset_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("preset")
    assert main(["preset", "fig2-2", "--quick", "0.05", "--out", str(out), "--movie"]) == 0
    return out


def test_preset_writes_every_file(preset_run):
    stems = sorted(p.name for p in preset_run.iterdir() if p.name != "summary.csv")
    assert stems == ["fig2-2a_sigma0_quick_x0.05", "fig2-2b_sigma0.15_quick_x0.05"]  # a folder per run
    for stem in stems:
        assert sorted(p.name for p in (preset_run / stem).iterdir()) == [stem + suffix for suffix in
                                                                         (".mp4", ".npz", ".png", ".toml")]
    table = rows(preset_run / "summary.csv")
    assert [r["sigma"] for r in table] == ["0.0", "0.15"]
    assert [r["state_file"] for r in table] == [f"{stem}/{stem}.npz" for stem in stems]
    assert all(0 <= float(r["max_overlap_pct_radius"]) < 5 for r in table)  # percent of a radius
    # the movie has one frame per 0.5 s of simulated time, from t = 0 to the end
    state = qdots.read_state(preset_run / stems[0] / f"{stems[0]}.npz")
    count = probe(preset_run / stems[0] / f"{stems[0]}.mp4")["frames"]
    assert count == int(np.floor(state.time / 0.5 + 1e-9)) + 1


def test_scene_file_runs_and_reproduces(preset_run, tmp_path):
    scene = next(preset_run.glob("*sigma0_*/*.toml"))
    assert main(["run", str(scene), "--out", str(tmp_path)]) == 0
    again = tmp_path / "again"
    assert main(["run", str(scene), "--out", str(again)]) == 0
    a = qdots.read_state(next(tmp_path.glob("*/*.npz")))
    b = qdots.read_state(next(again.glob("*/*.npz")))
    assert np.array_equal(a.positions, b.positions)
    other = tmp_path / "other"
    assert main(["run", str(scene), "--out", str(other), "--seed", "9"]) == 0
    assert not np.array_equal(a.positions, qdots.read_state(next(other.glob("*/*.npz"))).positions)


def test_resume_keeps_the_table_and_continues(preset_run, tmp_path):
    state = next(preset_run.glob("*sigma0_*/*.npz"))
    before = qdots.read_state(state)
    assert main(["resume", str(state), "--seconds", "0.5", "--out", str(tmp_path)]) == 0
    (folder,) = [p for p in tmp_path.iterdir() if p.is_dir()]
    moved = folder / f"{folder.name}.npz"
    assert folder.name == f"{state.stem}-t{before.time + 0.5:g}s"
    assert qdots.read_state(moved).time == pytest.approx(before.time + 0.5)
    assert main(["resume", str(moved), "--seconds", "0.3", "--in-place"]) == 0
    assert qdots.read_state(moved).time == pytest.approx(before.time + 0.8)
    (row,) = rows(tmp_path / "summary.csv")
    assert row["sigma"] == "0.0" and row["name"] == folder.name  # the parameters of the run it continues


def test_render(preset_run, tmp_path):
    state = next(preset_run.glob("*/*.npz"))
    png = tmp_path / "board.png"
    assert main(["render", str(state), "--out", str(png)]) == 0
    assert iio.imread(png).shape[2] in (3, 4)


def test_save_scenes_only(tmp_path):
    assert main(["preset", "fig2-3", "--save", str(tmp_path)]) == 0
    files = sorted(tmp_path.glob("*.toml"))
    assert len(files) == 2 and not list(tmp_path.glob("*.npz"))


@pytest.mark.parametrize(
    "argv, message",
    [
        (["run", "missing.toml"], "missing.toml"),
        (["resume", "missing.npz", "--seconds", "1"], "no such qdots state file"),
        (["resume", "x.npz"], "--seconds"),
        (["resume", "x.npz", "--seconds", "-1"], "must be > 0"),
        (["render", "missing.npz"], "no such qdots state file"),
        (["preset", "fig9-9"], "invalid choice"),
        (["run", "x.toml", "--quick", "2"], "must be in"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(argv, message, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("qdots: error:") and "\n" not in err and message in err


def test_corrupt_state_file_is_reported(tmp_path, capsys):
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"PK\x03\x04garbage")
    assert main(["render", str(bad)]) == 2
    assert "not a readable qdots state file" in capsys.readouterr().err


# -- boards out of the ordinary: saved, loaded, rendered, resumed ---------------------------------

def test_a_board_overlapping_a_wall_after_a_run_saves_loads_renders_and_resumes_in_place(tmp_path, capsys):
    scene = gravity_scene_file(tmp_path)
    out = tmp_path / "out"
    run_ok(main, ["run", str(scene), "--out", str(out)], capsys)
    saved = out / "grav" / "grav.npz"
    state = qdots.read_state(saved)  # a dot sits 0.01 px into the inelastic floor: still loads
    assert state.n_dots == 12
    run_ok(main, ["render", str(saved)], capsys)
    before = saved.read_bytes()
    run_ok(main, ["resume", str(saved), "--seconds", "3", "--in-place"], capsys)
    assert saved.read_bytes() != before
    assert qdots.load(saved).time == pytest.approx(6.0)
    # run again into the same directory: the good result is replaced by another good one
    run_ok(main, ["run", str(scene), "--out", str(out)], capsys)
    assert qdots.read_state(saved).time == pytest.approx(3.0)


def test_large_overlap_at_a_coarse_time_step_is_measured_and_warned_not_refused(tmp_path, capsys):
    # 60 dots under the thesis's centre gravity at its 20 ms frame, fixed sub-steps (false: the default
    # adaptive sub-steps would split the impacts): they overlap by ~30 % of a radius (measured)
    path = tmp_path / "coarse.toml"
    path.write_text(to_toml({"name": "coarse", "board": {"width": 200.0, "height": 200.0},
                             "deposition": {"n_dots": 60, "interval": 0.0, "settle": 1.0},
                             "engine": {"dt": 0.02, "overlap_tolerance": False},
                             "forces": [{"type": "CentreGravity", "centre": [100.0, 100.0]}]}))
    with pytest.warns(RuntimeWarning, match=r"radii per sub-step \(> 0\.5\)"):  # the engine says so as it runs
        assert main(["run", str(path), "--out", str(tmp_path / "out")]) == 0
    captured = capsys.readouterr()
    saved = tmp_path / "out" / "coarse" / "coarse.npz"
    state = qdots.read_state(saved)
    assert qdots.load(saved).engine.overlap_tolerance is None  # as the file said
    overlap = qdots.analysis.overlaps(state)[0]
    assert overlap > qdots.simulation.OVERLAP_WARNING  # measured and kept ...
    header, row = (tmp_path / "out" / "summary.csv").read_text().splitlines()[:2]
    assert float(row.split(",")[header.split(",").index("max_overlap_pct_radius")]) == pytest.approx(100 * overlap,
                                                                                                     rel=1e-6)
    assert "warning: coarse: dots overlap" in captured.err  # ... and said
    run_ok(main, ["render", str(saved)], capsys)


def test_dots_that_leave_an_open_board_are_counted_and_the_board_loads(tmp_path, capsys):
    path = tmp_path / "open.toml"
    path.write_text(to_toml({"name": "open", "board": {"width": 100.0, "height": 100.0, "closed": False},
                             "deposition": {"n_dots": 10, "interval": 0.0, "settle": 20.0},
                             "forces": [{"type": "Gravity", "acceleration": [0.0, -200.0]}]}))
    assert main(["run", str(path), "--out", str(tmp_path / "out")]) == 0
    err = capsys.readouterr().err
    state = qdots.read_state(tmp_path / "out" / "open" / "open.npz")
    escaped = qdots.analysis.escaped(state)
    assert escaped > 0 and f"{escaped} of 10 dots have left the open board" in err
    assert f",{escaped}," in (tmp_path / "out" / "summary.csv").read_text()
    sim = qdots.load(tmp_path / "out" / "open" / "open.npz")
    sim.run(0.1)  # and goes on


# -- more one-line errors: a run that blows up, paths that are not files ------------------------

def test_runaway_dots_are_reported_physically(tmp_path, capsys):
    text = to_toml({"deposition": {"n_dots": 5, "interval": 0.0, "settle": 1.0}, "engine": {"dt": 0.1},
                    "forces": [{"type": "Gravity", "acceleration": [0.0, -1e8]}]})
    assert "the dots left the model's range" in refused_run(main, tmp_path / "fast.toml", text, capsys)


def test_paths_that_are_not_files_are_said_to_be(tmp_path, capsys):
    """Both programs check a path before they read or write it (labrig.files)."""
    assert main(["run", str(tmp_path)]) == 2
    assert "is not a regular file" in one_line_error(capsys)
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    assert planarize_main(["run", str(fifo)]) == 2
    assert "is not a regular file" in one_line_error(capsys, "planarize")
    assert planarize_main(["scene", "hill", "--save", "."]) == 2
    assert "names a directory" in one_line_error(capsys, "planarize")
    assert planarize_main(["scene", "hill", "--save", str(tmp_path / "missing" / "hill.toml")]) == 2
    err = one_line_error(capsys, "planarize")
    assert "does not exist" in err and ".tmp" not in err


# -- where the commands write by default -----------------------------------------------------------

def test_measure_writes_into_its_own_folder_by_default_not_beside_the_image(tmp_path, capsys, monkeypatch):
    from PIL import Image

    from qdots.placement import random_sequential

    data = tmp_path / "data"
    data.mkdir()
    board = random_sequential(40, (160, 160), 14.0, 0.1, rng=3)[0]
    yy, xx = np.mgrid[:160, :160]
    picture = np.full((160, 160), 200.0)
    for x, y in board:
        picture[(xx - x) ** 2 + (yy - y) ** 2 <= 36] = 40
    picture += np.random.default_rng(3).normal(scale=12, size=picture.shape)  # a micrograph's noise
    Image.fromarray(np.clip(picture, 0, 255).astype(np.uint8)).save(data / "film.png")
    monkeypatch.chdir(tmp_path)
    printed = run_ok(main, ["measure", str(data / "film.png"), "--nm-per-px", "1", "--no-lqe"], capsys).out
    assert sorted(p.name for p in data.iterdir()) == ["film.png"]  # the data folder as it was
    # its table in words: how many clusters of 5 or more dots, and the largest one's share
    assert re.search(r"\n  aggregates +\d+ clusters of 5 or more dots; the largest cluster holds \d+\.\d % of the "
                     r"dots\n", printed)
    assert f"wrote {Path('qdots-measure') / 'film'}{os.sep}: film.npz" in printed
    assert sorted(p.name for p in (tmp_path / "qdots-measure" / "film").iterdir()) == [
        "film.npz", "film_detections.png", "film_summary.csv"]
