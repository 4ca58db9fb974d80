"""Sweep specifications: expansion, ranges, run identity, sweep files and their errors."""

import tracemalloc

import pytest
from helpers import one_line_error

from labrig.sweeps import Sweep, run_id
from labrig.sweeps.files import sweep_from_dict
from labrig.sweeps.spec import get_path, range_values, set_path
from qdots.cli import main as qdots_main
from qdots.cli.sweep import ExperimentRunner, load_sweep


def test_product_order_points_axes_then_seeds():
    sweep = Sweep(base={"a": 0, "b": "x", "seed": 7}, axes={"a": [1, 2], "b": ["u", "v"]},
                  points=[{"label": "p", "c": 1}, {"label": "q", "c": 2}], seeds=2)
    runs = sweep.runs()
    assert len(runs) == len(sweep) == 16
    assert [r.index for r in runs] == list(range(16))
    assert runs[0].columns == {"label": "p", "c": 1, "a": 1, "b": "u", "seed": 7}
    assert runs[1].columns == {"label": "p", "c": 1, "a": 1, "b": "u", "seed": 8}  # seeds vary fastest
    assert runs[2].columns["b"] == "v" and runs[4].columns["a"] == 2 and runs[8].columns["label"] == "q"
    assert runs[-1].params == {"a": 2, "b": "v", "seed": 8, "c": 2}
    assert sweep.swept == ["label", "c", "a", "b", "seed"]


def test_seed_list_and_default_first_seed():
    assert [r.params["seed"] for r in Sweep(base={}, seeds=[5, 3]).runs()] == [5, 3]
    assert [r.params["seed"] for r in Sweep(base={}, seeds=3).runs()] == [0, 1, 2]  # no base seed: from 0
    assert [r.params["s"]["k"] for r in Sweep(base={"s": {"k": 4}}, seeds=2, seed_key="s.k").runs()] == [4, 5]


def test_ranges():
    assert range_values("x", {"start": 0.0, "stop": 0.15, "step": 0.05}) == (0.0, 0.05, 0.1, 0.15)
    assert range_values("x", {"start": 0, "stop": 1, "num": 5}) == (0.0, 0.25, 0.5, 0.75, 1.0)
    assert range_values("n", {"start": 100, "stop": 300, "step": 100}) == (100, 200, 300)
    assert all(isinstance(v, int) for v in range_values("n", {"start": 0, "stop": 10, "num": 3}))
    assert range_values("x", {"start": 1.0, "stop": 0.0, "step": -0.5}) == (1.0, 0.5, 0.0)
    assert range_values("x", {"start": 0.1, "stop": 0.7, "step": 0.1})[-1] == 0.7  # rounded, end included
    for bad, words in [({"start": 0, "stop": 1}, "exactly one of num"),
                       ({"start": 0, "stop": 1, "num": 2, "step": 1}, "exactly one of num"),
                       ({"start": 0, "stop": 1, "stp": 1}, "unknown key 'stp'"),
                       ({"stop": 1, "num": 2}, "needs start"),
                       ({"start": 0, "stop": 1, "step": -1}, "step must be nonzero"),
                       ({"start": 0, "stop": 1, "num": 0}, "num must be an integer"),
                       ({"start": 0, "stop": float("nan"), "num": 2}, "finite number")]:
        with pytest.raises(ValueError, match=words):
            range_values("x", bad)


def test_run_id_is_the_canonical_parameters():
    assert run_id("k", {"a": 1, "b": {"c": 2}}) == run_id("k", {"b": {"c": 2}, "a": 1})
    assert run_id("k", {"a": 1}) != run_id("k", {"a": 2}) != run_id("other", {"a": 2})
    assert len(run_id("k", {})) == 16
    # a default spelled out or left implicit is the same run for a runner that fills defaults in
    runner = ExperimentRunner()
    implicit = Sweep(base={"deposition": {"n_dots": 5}}).runs(runner.canonical, runner.kind)[0]
    explicit = Sweep(base={"deposition": {"n_dots": 5, "sigma": 0.0}, "seed": 154}).runs(runner.canonical, runner.kind)[0]
    assert implicit.id == explicit.id
    assert ExperimentRunner(quick=0.5).canonical({"deposition": {"n_dots": 10}})["deposition"]["n_dots"] == 5


def test_paths():
    tree = {"a": {"b": 1}, "forces": [{"r0": 1.0}]}
    set_path(tree, "a.c", 2)
    set_path(tree, "forces.0.r0", 3.0)
    set_path(tree, "new.deep", 4)
    assert tree == {"a": {"b": 1, "c": 2}, "forces": [{"r0": 3.0}], "new": {"deep": 4}}
    assert get_path(tree, "forces.0.r0") == 3.0 and get_path(tree, "a.x", None) is None
    with pytest.raises(ValueError, match="cannot set 'a.b.c': a.b is 1, not a table"):
        set_path(tree, "a.b.c", 0)
    with pytest.raises(ValueError, match="not an index"):
        set_path(tree, "forces.3.r0", 0)
    with pytest.raises(ValueError, match="dotted name"):
        set_path(tree, "a..b", 0)


@pytest.mark.parametrize("kwargs, words", [
    ({"axes": {"x": []}}, "non-empty list"),
    ({"axes": {"x": [1, 1]}}, "lists 1 twice"),
    ({"axes": {"x": 3}}, "non-empty list of values or a range"),
    ({"seeds": 0}, r"seeds must be an integer in \[1, "),
    ({"seeds": [1, 1]}, "twice"),
    ({"seeds": [-1]}, r"list of integers in \[0, "),
    ({"points": [{"label": "a"}, {}]}, "all have a label"),
    ({"points": [{"label": "a"}, {"label": "a"}]}, "each different"),
    ({"points": []}, "non-empty list"),
    ({"axes": {"seed": [1, 2]}, "seeds": 2}, "set by seeds"),
])
def test_bad_sweeps(kwargs, words):
    with pytest.raises(ValueError, match=words):
        Sweep(base={"x": 0}, **kwargs)


def test_runs_name_the_bad_key_and_duplicates():
    runner = ExperimentRunner()
    with pytest.raises(ValueError, match=r"axes.deposition.sigmaa: unknown key 'deposition.sigmaa'"):
        Sweep(base={}, axes={"deposition.sigmaa": [0.1]}).runs(runner.canonical, runner.kind)
    with pytest.raises(ValueError, match=r"points\[1\]: deposition.sigma must be in"):
        Sweep(base={}, points=[{}, {"deposition.sigma": 2.0}]).runs(runner.canonical, runner.kind)
    with pytest.raises(ValueError, match=r"^base: unknown key 'colour'"):
        Sweep(base={"colour": 1}).runs(runner.canonical, runner.kind)
    with pytest.raises(ValueError, match="same parameters as run 0"):  # 10 and 11 dots are both 1 dot at x0.1
        Sweep(base={}, axes={"deposition.n_dots": [10, 11]}).runs(ExperimentRunner(quick=0.1).canonical, "q")


def test_sweep_file(tmp_path):
    (tmp_path / "scene.toml").write_text("seed = 10\n[deposition]\nn_dots = 4\n")
    (tmp_path / "sweep.toml").write_text(
        'base = "scene.toml"\nseeds = 2\n'
        '[axes]\n"deposition.sigma" = [0.0, 0.1]\nboard.width = {start = 100, stop = 200, num = 2}\n'
        '[[points]]\nlabel = "free"\n[[points]]\nlabel = "wide"\nboard.height = 700.0\n'
        '[output]\ndir = "results"\nstate = true\n')
    parsed = load_sweep(tmp_path / "sweep.toml")
    assert parsed.out == tmp_path / "results" and parsed.state
    sweep = parsed.sweep
    assert sweep.axes == {"deposition.sigma": (0.0, 0.1), "board.width": (100.0, 200.0)}
    assert sweep.points == ({"label": "free"}, {"label": "wide", "board.height": 700.0})
    runs = sweep.runs(ExperimentRunner().canonical)
    assert len(runs) == 16 and {r.params["seed"] for r in runs} == {10, 11}
    assert runs[-1].params["board"] == {"width": 200.0, "height": 700.0, "closed": True}


@pytest.mark.parametrize("text, words", [
    ('base = "scene.toml"\ncolour = 1\n', "unknown key 'colour' (allowed: base, axes, points, seeds, output)"),
    ("seeds = 2\n", 'missing key "base"'),
    ('base = "scene.toml"\n[output]\nfolder = "x"\n', "unknown key 'output.folder'"),
    ('base = "scene.toml"\n[output]\nstate = "yes"\n', "output.state must be true or false"),
    ('base = "scene.toml"\naxes = 3\n', "axes must be a table"),
    ('base = "scene.toml"\n[axes]\nx = {start = 0, stop = 1}\n', "axes.x needs exactly one of num"),
    ('base = "scene.toml"\nseeds = "four"\n', "seeds must be a count"),
    ('base = 3\n', "base must be a file name or a table"),
    ('base = "scene.toml"\n[axes\n', "invalid TOML"),
])
def test_bad_sweep_files(tmp_path, text, words):
    (tmp_path / "scene.toml").write_text("")
    path = tmp_path / "sweep.toml"
    path.write_text(text)
    with pytest.raises(ValueError, match=f"^{path}: .*") as info:
        load_sweep(path)
    assert words in str(info.value)


def test_missing_files(tmp_path):
    with pytest.raises(FileNotFoundError, match="sweep file"):
        load_sweep(tmp_path / "none.toml")
    (tmp_path / "sweep.toml").write_text('base = "none.toml"\n')
    with pytest.raises(FileNotFoundError, match="base file .*none.toml"):
        load_sweep(tmp_path / "sweep.toml")


def test_a_huge_seed_count_is_refused_before_anything_is_allocated(tmp_path, capsys):
    (tmp_path / "sweep.toml").write_text("seeds = 1000000000\n[base]\nname = 'x'\n")
    tracemalloc.start()
    try:
        assert qdots_main(["sweep", str(tmp_path / "sweep.toml"), "--workers", "1"]) == 2
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert "seeds must be an integer in [1, 100,000]" in one_line_error(capsys)
    assert peak < 50e6  # a billion seeds would be gigabytes


def test_inline_base_and_dotted_points():
    parsed = sweep_from_dict({"base": {"deposition": {"n_dots": 3}}, "points": [{"deposition": {"sigma": 0.1}}]})
    assert parsed.sweep.points == ({"deposition.sigma": 0.1},)
    assert parsed.sweep.runs(ExperimentRunner().canonical)[0].params["deposition"]["sigma"] == 0.1
