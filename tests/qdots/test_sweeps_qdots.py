"""qdots experiment sweeps: the same table locally and on a Dask cluster, states, the command line."""

import dataclasses
import math

import numpy as np
import pytest

import qdots
from labrig.sweeps import Sweep, read_table, run_sweep
from qdots.analysis import packing_summary
from qdots.cli import main
from qdots.cli.sweep import ExperimentRunner, experiment_to_dict
from qdots.experiment import Board, Deposition, Experiment, run_experiment
from qdots.io.experiment_file import experiment_from_dict, save_experiment

#: A few dots and about 1 s of simulated time per run.
TINY = Experiment(name="tiny", board=Board(120.0, 120.0),
                  deposition=Deposition(n_dots=6, interval=0.1, settle=0.6))
#: 2 sigma x 2 mass models x 2 seeds.
SWEEP = Sweep(base=experiment_to_dict(TINY),
              axes={"deposition.sigma": [0.0, 0.15], "deposition.mass_model": ["equal", "volume"]}, seeds=2)


def same(a, b):
    return a == b or (isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b))


def without_wall_time(rows):
    return [{k: v for k, v in row.items() if k != "wall_s"} for row in rows]


def assert_same_tables(a, b):
    a, b = without_wall_time(a), without_wall_time(b)
    assert [list(r) for r in a] == [list(r) for r in b]
    mismatched = [(k, ra[k], rb[k]) for ra, rb in zip(a, b) for k in ra if not same(ra[k], rb[k])]
    assert not mismatched


@pytest.fixture(scope="module")
def local(tmp_path_factory):
    out = tmp_path_factory.mktemp("local")
    return run_sweep(SWEEP, ExperimentRunner(), out, workers=2, state=True, progress=False), out


def test_experiment_dict_round_trip():
    assert experiment_from_dict(experiment_to_dict(TINY)) == TINY
    exp = TINY.replace(forces=(qdots.VanDerWaals(strength=2.0).to_dict(), qdots.CentreGravity((60, 60), 5).to_dict()))
    assert experiment_from_dict(experiment_to_dict(exp)) == exp


def test_local_sweep_rows_are_the_runs(local):
    result, out = local
    assert (result.ran, result.failed, len(result.rows)) == (8, 0, 8)
    row = result.rows[5]  # sigma 0.15, equal masses, second seed
    assert (row["deposition.sigma"], row["deposition.mass_model"], row["seed"]) == (0.15, "equal", 155)
    exp = TINY.replace(seed=155, deposition=dataclasses.replace(TINY.deposition, sigma=0.15))
    sim = run_experiment(exp)
    expected = packing_summary(sim.state())
    expected["max_overlap_pct_radius"] = 100 * expected.pop("max_overlap")  # the table's column: percent
    assert all(same(row[key], value) for key, value in expected.items())
    assert row["steps"] == sim.steps_taken
    saved = qdots.read_state(out / row["state_file"])
    assert np.array_equal(saved.positions, sim.state().positions)
    # every parameter is a column
    for key in ("board.width", "engine.dt", "restitution.mean", "forces.0.type", "forces.1.interval", "name"):
        assert key in row


def test_dask_local_cluster_gives_the_same_table(local, tmp_path):
    distributed = pytest.importorskip("distributed")
    save_experiment(TINY, tmp_path / "tiny.toml")
    (tmp_path / "sweep.toml").write_text(
        'base = "tiny.toml"\nseeds = 2\n[axes]\n"deposition.sigma" = [0.0, 0.15]\n'
        '"deposition.mass_model" = ["equal", "volume"]\n[output]\nstate = true\n')
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        on_dask = run_sweep(SWEEP, ExperimentRunner(), tmp_path / "api", scheduler=cluster.scheduler_address,
                            state=True, progress=False)
        assert main(["sweep", str(tmp_path / "sweep.toml"), "--scheduler", cluster.scheduler_address]) == 0
    assert on_dask.failed == 0
    assert_same_tables(local[0].rows, on_dask.rows)
    assert_same_tables(local[0].rows, read_table(tmp_path / "sweep" / "table.csv"))
    serial = run_sweep(SWEEP, ExperimentRunner(), tmp_path / "serial", workers=1, progress=False)
    assert_same_tables([{k: v for k, v in r.items() if k != "state_file"} for r in local[0].rows],
                       [{k: v for k, v in r.items() if k != "state_file"} for r in serial.rows])


def write_sweep(tmp_path, extra=""):
    save_experiment(TINY, tmp_path / "tiny.toml")
    path = tmp_path / "sweep.toml"
    path.write_text('base = "tiny.toml"\nseeds = 2\n[axes]\n"deposition.sigma" = [0.0, 0.15]\n'
                    '[[points]]\nlabel = "free"\n[[points]]\nlabel = "grating"\ngrating = 40.0\n' + extra)
    return path


def test_command_line_sweep_and_plot(tmp_path, capsys):
    path = write_sweep(tmp_path)
    assert main(["sweep", str(path), "--workers", "2", "--quick", "0.5"]) == 0
    table = tmp_path / "sweep" / "table.csv"
    rows = read_table(table)
    assert len(rows) == 8 and {r["deposition.n_dots"] for r in rows} == {3}  # quick: half the dots
    assert [r["label"] for r in rows[::2]] == ["free", "free", "grating", "grating"]
    printed = capsys.readouterr().out
    assert "already done" in printed
    # said before anything ran: the count, what is left, the workers, a time estimate, the resolved directory
    assert "sweep: 8 runs (2 points x 2 deposition.sigma x 2 seeds): 0 finished before, 8 to run on 2 workers, " \
           "about " in printed and f"; output: {(tmp_path / 'sweep').resolve()}\n" in printed
    assert main(["sweep", str(path), "--quick", "0.5", "--workers", "1"]) == 0
    assert "already done  8" in capsys.readouterr().out
    assert main(["sweep-plot", str(table), "--metric", "mean_neighbours", "--x", "deposition.sigma",
                 "--group", "label"]) == 0
    printed = capsys.readouterr().out
    png = tmp_path / "sweep" / "mean_neighbours_vs_deposition.sigma_by_label.png"
    assert png.read_bytes()[:4] == b"\x89PNG" and str(png) in printed
    free = [r["mean_neighbours"] for r in rows if r["label"] == "free" and r["deposition.sigma"] == 0.15]
    assert f"{np.mean(free):.6g}" in printed and f"{np.std(free, ddof=1) / np.sqrt(2):.3g}" in printed
    # averaging over the groups is refused: label is swept
    assert main(["sweep-plot", str(table), "--metric", "mean_neighbours", "--x", "deposition.sigma"]) == 2
    assert "'label' varies" in capsys.readouterr().err


@pytest.mark.parametrize("extra, words", [
    ('[output]\ncolour = 1\n', "unknown key 'output.colour'"),
    ('[axes.deposition]\nsigmaa = [0.1]\n', "axes.deposition.sigmaa: unknown key 'deposition.sigmaa'"),
    ('[axes.deposition]\nn_dots = {start = 5, stop = 1, step = 1}\n', "step must be nonzero"),
])
def test_command_line_bad_sweep_files(tmp_path, capsys, extra, words):
    path = write_sweep(tmp_path, extra)
    assert main(["sweep", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("qdots: error: ") and words in err and err.count("\n") == 1
    assert not (tmp_path / "sweep" / "table.csv").exists()


def test_a_sweep_larger_than_its_bound_is_refused_before_anything_runs(tmp_path, capsys):
    """300 x 300 = 90,000 runs used to start without a word."""
    path = write_sweep(tmp_path, '[axes.board]\nwidth = {start = 300, stop = 599, num = 300}\n'
                                 'height = {start = 300, stop = 599, num = 300}\n')
    assert main(["sweep", str(path)]) == 2
    err = capsys.readouterr().err
    assert "the sweep has 720,000 runs (points x axes x seeds), more than the 100,000 a sweep may have" in err
    path = write_sweep(tmp_path, '[axes.board]\nwidth = {start = 300, stop = 599, num = 300}\n')
    assert main(["sweep", str(path), "--workers", "1"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("qdots: error: the sweep has 2,400 runs (2 points x 2 deposition.sigma x 300 board.width x "
                          "2 seeds), more than the 1,000 it may start: raise max_runs (--max-runs") and err.count("\n") == 1
    assert not (tmp_path / "sweep").exists()
    assert main(["sweep", str(path), "--max-runs", "100001"]) == 2
    assert "--max-runs: must be an integer in [1, 100,000]" in capsys.readouterr().err


def test_an_output_directory_that_is_a_dangling_link_is_named(tmp_path, capsys):
    path = write_sweep(tmp_path)
    (tmp_path / "sweep").symlink_to(tmp_path / "gone")
    assert main(["sweep", str(path), "--workers", "1"]) == 2
    err = capsys.readouterr().err
    assert "is a symbolic link to" in err and "which does not exist" in err and "Errno" not in err


def test_failed_runs_give_exit_status_1(tmp_path, capsys, monkeypatch):
    import qdots.cli.sweep as module

    def flaky_run(exp):
        if exp.deposition.sigma > 0:
            raise RuntimeError("deposition blew up")
        return run_experiment(exp)

    monkeypatch.setattr(module, "run_experiment", flaky_run)  # workers=1 runs in this process
    path = write_sweep(tmp_path)
    assert main(["sweep", str(path), "--workers", "1"]) == 1
    err = capsys.readouterr().err
    rows = read_table(tmp_path / "sweep" / "table.csv")
    failed = [r for r in rows if r["status"] == "failed"]
    assert len(failed) == 4 and all(r["deposition.sigma"] == 0.15 for r in failed)
    assert all(r["error"] == "RuntimeError: deposition blew up" and r["attempts"] == 2 for r in failed)
    assert err.count("failed: RuntimeError: deposition blew up") == 4
    assert all(r["status"] == "ok" for r in rows if r["deposition.sigma"] == 0.0)


def test_the_engine_is_a_sweep_axis_and_each_run_is_that_engines(tmp_path):
    sweep = Sweep(base=experiment_to_dict(TINY), axes={"engine.kind": ["chipmunk", "event"]}, seeds=1)
    result = run_sweep(sweep, ExperimentRunner(), tmp_path, workers=1, state=True, progress=False)
    rows = {row["engine.kind"]: row for row in result.rows}
    assert sorted(rows) == ["chipmunk", "event"] and all(row["status"] == "ok" for row in rows.values())
    for kind, row in rows.items():  # the same film by the other engine is the same experiment run differently
        again = run_experiment(dataclasses.replace(TINY, seed=row["seed"],
                                                   engine=TINY.engine.replace(kind=kind))).state()
        saved = qdots.read_state(tmp_path / row["state_file"])
        np.testing.assert_array_equal(saved.positions, again.positions)
    assert not np.array_equal(*(qdots.read_state(tmp_path / row["state_file"]).positions for row in rows.values()))
