"""``qdots analyze``: table, JSON and figure of a saved state; bad input exits 2."""

import json
import re

import numpy as np
import pytest
from helpers import run_ok

import qdots
from qdots.cli import main
from qdots.placement import hexagonal_lattice


@pytest.fixture(scope="module")
def state_file(tmp_path_factory):
    """A saved hexagonal flake of 19 dots (exact numbers known) plus one far-away dot."""
    positions = np.vstack([hexagonal_lattice(2, 15.0, "flake", (100.0, 100.0)), [[250.0, 250.0]]])
    scene = qdots.Scene(box=(300.0, 300.0), positions=positions, radii=np.full(len(positions), 7.5),
                        overlap_tolerance=1e-6)
    sim = qdots.Simulation(scene, [], seed=1)
    path = tmp_path_factory.mktemp("analyze") / "flake.npz"
    qdots.save(sim, path)
    return path


def test_analyze_json_has_the_exact_packing_numbers(state_file, capsys):
    assert main(["analyze", str(state_file), "--json", "--draws", "2"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["n_dots"] == 20
    assert out["interior_fraction"] == pytest.approx(7 / 20)  # 1 + 6 dots of the flake's inner part
    assert out["mean_neighbours_interior"] == 6.0
    assert out["psi6_global"] == pytest.approx(1.0)  # the lone dot has no neighbours and is left out
    assert out["clusters"] == 2 and out["largest_cluster_fraction"] == pytest.approx(19 / 20)
    assert 0 < out["lqe"] < out["solution_lqe"] <= 1
    assert out["size_separation_correlation"] is None  # equal sizes: undefined, null in JSON
    assert out["trap_draws"] == 2 and out["forster_radius_px"] == 15.0
    assert main(["analyze", str(state_file), "--json", "--draws", "2", "--forster-radii", "1"]) == 0
    in_radii = json.loads(capsys.readouterr().out)
    assert in_radii["forster_radius_px"] == 7.5 and in_radii["lqe"] > out["lqe"]


def test_analyze_json_is_strict_json(tmp_path, capsys, good_state):
    text = run_ok(main, ["analyze", str(good_state), "--json"], capsys).out

    def refuse(constant):
        raise AssertionError(f"{constant} is not JSON")

    summary = json.loads(text, parse_constant=refuse)
    assert summary["n_dots"] == 2


def test_analyze_table_and_plot(state_file, tmp_path, capsys):
    png = tmp_path / "fig.png"
    assert main(["analyze", str(state_file), "--plot", str(png), "--rule", "code", "--traps", "0.5",
                 "--forster-radius", "20", "--draws", "1"]) == 0
    text = capsys.readouterr().out
    assert "interior fraction" in text and "film LQE (exact)" in text and f"wrote {png}" in text
    # equal sizes: the correlation is said to be undefined, not printed as a bare nan
    assert re.search(r"size-separation correlation +undefined for equal sizes\n", text) and "nan" not in text
    assert re.search(r"size spread \(SD / mean diameter\) +0.0 %\n", text)
    assert re.search(r"film LQE \(exact\) +0.\d{4} for one trap draw \(no standard error\)", text)
    assert png.stat().st_size > 10_000
    assert main(["analyze", str(state_file), "--plot", "--draws", "1"]) == 0
    assert state_file.with_name("flake_analysis.png").exists()


def test_the_table_says_in_words_what_a_neighbour_and_a_cluster_are(state_file, capsys):
    assert main(["analyze", str(state_file), "--draws", "1"]) == 0
    text = capsys.readouterr().out
    assert "neighbour rule" not in text and "'text'" not in text  # no code names
    assert text.splitlines()[0] == f"{state_file} at t = 0.00 s:"
    assert re.search(r"\n  neighbours +two dots whose surfaces are less than one mean radius apart \(the thesis's "
                     r"text; --rule code: its program\)\n", text)
    assert re.search(r"clusters of neighbouring dots +2; the largest holds 95.0 % of the dots\n", text)
    assert main(["analyze", str(state_file), "--draws", "1", "--rule", "code"]) == 0
    assert "dot j of dot i when their centres are at most r_i + 2 r_j apart" in capsys.readouterr().out


@pytest.mark.parametrize("argv, message", [
    (["--traps", "1.5"], "--traps"),
    (["--rule", "java"], "--rule"),
    (["--forster-radius", "-3"], "--forster-radius"),
    (["--forster-radius", "1e300"], "--forster-radius: must be in (0, 1e9]"),
    (["--forster-radius", "1"], "forster_radii=1"),
    (["--forster-radius", "15", "--forster-radii", "2"], "not allowed with"),
    (["--forster-radii", "0"], "--forster-radii"),
    (["--draws", "0"], "--draws"),
])
def test_analyze_rejects_bad_options(state_file, argv, message, capsys):
    assert main(["analyze", str(state_file), *argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("qdots: error:") and message in err and len(err.strip().splitlines()) == 1


def test_analyze_missing_or_corrupt_file(tmp_path, capsys):
    assert main(["analyze", str(tmp_path / "none.npz")]) == 2
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip")
    assert main(["analyze", str(bad)]) == 2
    assert capsys.readouterr().err.count("qdots: error:") == 2
