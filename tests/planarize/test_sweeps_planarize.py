"""planarize sweeps: rows equal direct runs, scene-file validation, seeds, Fig 3-13 as a sweep file."""

import math

import pytest

import planarize
from labrig.sweeps import Sweep, run_sweep
from planarize.cli.sweep import AnodizeRunner, load_sweep, scene_to_dict
from planarize.io.results import load_run
from planarize.io.scenefile import scene_from_dict
from planarize.scene import SCENES

#: The thesis hill on its unrefined 5 x 5 grid, coarse steps: milliseconds per run.
TINY = {"surface": {"kind": "hill", "refine": 1}, "run": {"thickness": 0.3, "step": 0.05, "record": [0.1, 0.2, 0.3]}}


def test_scene_dict_round_trip():
    for scene in SCENES.values():
        assert scene_from_dict(scene_to_dict(scene)) == scene


def test_rows_are_the_runs(tmp_path):
    sweep = Sweep(base=TINY, axes={"run.k_exp": [1.3, 2.3]})
    result = run_sweep(sweep, AnodizeRunner(), tmp_path, workers=2, state=True, progress=False)
    assert result.failed == 0 and [r["run.k_exp"] for r in result.rows] == [1.3, 2.3]
    for row in result.rows:
        direct = planarize.anodize(planarize.surfaces.hill(refine=1), 0.3, planarize.Model(step=0.05, k_exp=row["run.k_exp"]),
                                   record=[0.1, 0.2, 0.3])
        h = direct.history
        assert row["oxide_rms_nm"] == h["oxide_rms_nm"][-1] and row["metal_zrange_nm"] == h["metal_zrange_nm"][-1]
        assert row["oxide_rms_nm@0.1"] == h["oxide_rms_nm"][0] and row["metal_rms_nm@0.2"] == h["metal_rms_nm"][1]
        assert "oxide_rms_nm@0.3" not in row  # the end is the plain column
        assert abs(row["volume_error"]) < 1e-2 and row["thickness_nm"] >= 0.3
        saved = load_run(tmp_path / row["state_file"])
        assert (saved.oxide.z == direct.oxide.z).all()
    assert result.rows[0]["run.step"] == 0.05 and result.rows[0]["surface.refine"] == 1


def test_seeds_seed_random_surfaces(tmp_path):
    base = {"surface": {"kind": "random_roughness", "size": 100.0, "thickness": 50.0, "scales": [[40.0, 10.0]],
                        "refine": 1}, "run": {"thickness": 0.5, "step": 0.5}}
    rows = run_sweep(Sweep(base=base, seeds=2), AnodizeRunner(), tmp_path, workers=1, progress=False).rows
    assert [r["seed"] for r in rows] == [0, 1]
    assert rows[0]["metal_rms_initial_nm"] != rows[1]["metal_rms_initial_nm"]
    again = run_sweep(Sweep(base=base, seeds=[1]), AnodizeRunner(), tmp_path / "again", workers=1, progress=False)
    assert again.rows[0]["metal_rms_initial_nm"] == rows[1]["metal_rms_initial_nm"]


def test_bad_parameters_name_the_key():
    runner = AnodizeRunner()
    with pytest.raises(ValueError, match=r"axes.run.k_exps: unknown key 'run.k_exps'"):
        Sweep(base=TINY, axes={"run.k_exps": [2.0]}).runs(runner.canonical)
    with pytest.raises(ValueError, match=r"run 1 \(run.k_exp=0.5\): run.k_exp must be in \[1, 5\]"):
        Sweep(base=TINY, axes={"run.k_exp": [2.0, 0.5]}).runs(runner.canonical)
    with pytest.raises(ValueError, match="surface.kind must be one of"):
        Sweep(base={"surface": {"kind": "hil"}}).runs(runner.canonical)
    quick = AnodizeRunner(quick=0.5).canonical(scene_to_dict(SCENES["hill"]))
    assert quick["run"]["step"] == 0.02 and quick["surface"]["refine"] == 2


FIG_3_13 = """
base = "hill"
[axes]
"run.k_exp" = [1.3, 1.8, 2.0, 2.3, 2.8]
"""


def test_fig_3_13_sweep_file(tmp_path):
    path = tmp_path / "fig3-13.toml"
    path.write_text(FIG_3_13)
    parsed = load_sweep(path)
    runs = parsed.sweep.runs(AnodizeRunner().canonical)
    assert [r.params["run"]["k_exp"] for r in runs] == [1.3, 1.8, 2.0, 2.3, 2.8]
    assert all(r.params["surface"]["kind"] == "hill" and r.params["run"]["step"] == 0.01 for r in runs)
    path.write_text('base = "hil"\n')
    with pytest.raises(ValueError, match="neither a built-in scene"):
        load_sweep(path)


def test_command_line(tmp_path, capsys):
    main = pytest.importorskip("planarize.cli").main
    path = tmp_path / "k.toml"
    path.write_text('[base]\nsurface.kind = "hill"\nsurface.refine = 1\nrun.thickness = 0.3\nrun.step = 0.05\n'
                    '[axes]\n"run.k_exp" = [1.5, 2.0, 2.5]\n[output]\ndir = "k"\n')
    assert main(["sweep", str(path), "--workers", "1"]) == 0
    assert main(["sweep-plot", str(tmp_path / "k" / "table.csv"), "--metric", "oxide_rms_nm", "--x", "run.k_exp",
                 "--out", str(tmp_path / "k.png")]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert (tmp_path / "k.png").read_bytes()[:4] == b"\x89PNG"
    assert any(line.split()[:2] == ["2.0", "1"] for line in lines)
    assert math.isfinite(float(next(line.split()[2] for line in lines if line.split()[:1] == ["2.0"])))
    path.write_text('base = "hill"\n[axes]\n"run.kexp" = [1.5]\n')
    assert main(["sweep", str(path)]) == 2
    assert "unknown key 'run.kexp'" in capsys.readouterr().err


def test_an_axis_of_engines_switches_the_engine_of_a_named_base(tmp_path):
    (tmp_path / "engines.toml").write_text('base = "hill"\n[axes]\n"engine.kind" = ["fast", "reference"]\n'
                                           '"run.thickness" = [0.05]\n')
    sweep = load_sweep(tmp_path / "engines.toml").sweep
    runs = sweep.runs(AnodizeRunner(quick=0.25).canonical)
    assert [run.params["engine"] for run in runs] == [{"kind": "fast", "interacting": "wait"}, {"kind": "reference"}]
    (tmp_path / "old.toml").write_text('base = "hill"\n[axes]\n"run.engine" = ["fast"]\n')
    with pytest.raises(ValueError, match=r"axes.run.engine: run.engine: the engine and its settings are the \[engine\] "
                                         r"table's: write it as engine.kind"):
        load_sweep(tmp_path / "old.toml").sweep.runs(AnodizeRunner().canonical)
