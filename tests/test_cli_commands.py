"""qdots run / preset / resume / render: files written, exit codes, one-line errors."""

import csv

import imageio.v2 as imageio
import imageio.v3 as iio
import numpy as np
import pytest

import qdots
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
    names = sorted(p.name for p in preset_run.iterdir())
    stems = sorted({n.rsplit(".", 1)[0] for n in names if n != "summary.csv"})
    assert len(stems) == 2  # sigma 0 and 0.15
    for stem in stems:
        for suffix in (".npz", ".png", ".toml", ".mp4"):
            assert stem + suffix in names
    table = rows(preset_run / "summary.csv")
    assert [r["sigma"] for r in table] == ["0.0", "0.15"]
    assert all(0 <= float(r["max_overlap_pct_radius"]) < 5 for r in table)  # percent of a radius
    # the movie has one frame per 0.5 s of simulated time, from t = 0 to the end
    state = qdots.read_state(preset_run / f"{stems[0]}.npz")
    reader = imageio.get_reader(preset_run / f"{stems[0]}.mp4")
    count = sum(1 for _ in reader)
    reader.close()
    assert count == int(np.floor(state.time / 0.5 + 1e-9)) + 1


def test_scene_file_runs_and_reproduces(preset_run, tmp_path):
    scene = next(preset_run.glob("*sigma0_*.toml"))
    assert main(["run", str(scene), "--out", str(tmp_path)]) == 0
    again = tmp_path / "again"
    assert main(["run", str(scene), "--out", str(again)]) == 0
    a = qdots.read_state(next(tmp_path.glob("*.npz")))
    b = qdots.read_state(next(again.glob("*.npz")))
    assert np.array_equal(a.positions, b.positions)
    other = tmp_path / "other"
    assert main(["run", str(scene), "--out", str(other), "--seed", "9"]) == 0
    assert not np.array_equal(a.positions, qdots.read_state(next(other.glob("*.npz"))).positions)


def test_resume_keeps_the_table_and_continues(preset_run, tmp_path):
    state = next(preset_run.glob("*sigma0_*.npz"))
    before = qdots.read_state(state)
    assert main(["resume", str(state), "--seconds", "0.5", "--out", str(tmp_path)]) == 0
    after = qdots.read_state(tmp_path / state.name)
    assert after.time == pytest.approx(before.time + 0.5)
    assert main(["resume", str(tmp_path / state.name), "--seconds", "0.25"]) == 0
    assert qdots.read_state(tmp_path / state.name).time == pytest.approx(before.time + 0.75)
    assert len(rows(tmp_path / "summary.csv")) == 1


def test_render(preset_run, tmp_path):
    state = next(preset_run.glob("*.npz"))
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
