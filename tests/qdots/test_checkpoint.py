"""Save, load, resume: bit-identical continuation, atomic writes, clear errors on bad files (from Python and from
the command line), dots added to a saved run, state files of earlier versions."""

import json
import warnings
import zipfile

import numpy as np
import pytest
from helpers import one_line_error

import labrig.archive
import qdots
from qdots.cli import main as qdots_main
from qdots.io import checkpoint


def busy_simulation(seed=7, n=80):
    rng = np.random.default_rng(1)
    grid = np.array([(x, y) for x in range(20, 220, 19) for y in range(20, 220, 19)], float)[:n]
    scene = qdots.Scene(box=(240, 240), positions=grid, radii=rng.uniform(6.5, 8.5, n).clip(max=9.0),
                        masses=rng.uniform(0.5, 2.0, n), velocities=rng.normal(0, 20, (n, 2)),
                        segments=[[0, 120, 60, 120]])
    forces = [qdots.VanDerWaals(), qdots.ThermalKicks(), qdots.Drag(), qdots.Langevin(0.5, 2.0)]
    return qdots.Simulation(scene, forces, seed=seed, substeps=2, collision_slop=0.02)


def assert_same_run(a: qdots.Simulation, b: qdots.Simulation):
    sa, sb = a.state(), b.state()
    assert sa.time == sb.time
    assert np.array_equal(sa.positions, sb.positions)
    assert np.array_equal(sa.velocities, sb.velocities)
    assert a.rng.bit_generator.state == b.rng.bit_generator.state
    assert (a.collisions.dot_dot, a.collisions.dot_wall) == (b.collisions.dot_dot, b.collisions.dot_wall)


def test_resume_is_bit_identical(tmp_path):
    path = tmp_path / "run.npz"
    live = busy_simulation()
    live.run(0.4)
    checkpoint.save(live, path)
    live.run(0.6)
    resumed = checkpoint.load(path)
    assert resumed.time == pytest.approx(0.4)
    resumed.run(0.6)
    assert live.collisions.dot_dot > 10  # random draws happened after the checkpoint
    assert_same_run(live, resumed)


def test_resume_after_deposition(tmp_path):
    live = busy_simulation(n=30)
    live.run(0.1)
    live.add_dots([[200, 200]], [7.0], masses=[3.0], velocities=[[5.0, -5.0]])
    live.run(0.1)
    qdots.save(live, tmp_path / "a.npz")
    resumed = qdots.load(tmp_path / "a.npz")
    assert resumed.n_dots == 31 and resumed.masses[-1] == 3.0
    live.run(0.3)
    resumed.run(0.3)
    assert_same_run(live, resumed)


def test_saved_file_is_plain_numpy_and_json(tmp_path):
    sim = busy_simulation()
    sim.run(0.04)
    path = qdots.save(sim, tmp_path / "state.npz")
    with np.load(path, allow_pickle=False) as f:
        meta = json.loads(str(f["metadata"]))
        assert f["positions"].shape == (80, 2)
        assert f["segments"].tolist() == [[0, 120, 60, 120]]
    assert meta["format"] == "qdots-state" and meta["version"] == 1
    assert meta["steps_taken"] == round(0.04 / qdots.Chipmunk().dt) and meta["engine"]["substeps"] == 2
    assert [f["type"] for f in meta["forces"]] == ["VanDerWaals", "ThermalKicks", "Drag", "Langevin"]
    state = qdots.read_state(path)
    np.testing.assert_array_equal(state.positions, sim.state().positions)
    assert state.time == pytest.approx(0.04) and state.walls.shape == (5, 4)


def test_crash_mid_write_keeps_the_old_file(tmp_path, monkeypatch):
    path = tmp_path / "run.npz"
    sim = busy_simulation()
    sim.run(0.04)
    qdots.save(sim, path)
    before = path.read_bytes()
    sim.run(0.05)

    def crash(stream, **arrays):
        stream.write(b"PK\x03\x04 partial")
        raise OSError("disk full")

    monkeypatch.setattr(labrig.archive.np, "savez", crash)
    with pytest.raises(OSError, match="disk full"):
        qdots.save(sim, path)
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.npz"]  # no temporary left behind
    assert qdots.read_state(path).time == pytest.approx(0.04)


# ---------------------------------------------------------------- bad files: one clear error each
@pytest.fixture
def saved(tmp_path):
    sim = busy_simulation()
    sim.run(0.02)
    return qdots.save(sim, tmp_path / "good.npz")


def test_truncated_file_is_a_clear_error(saved):
    data = saved.read_bytes()
    saved.write_bytes(data[: len(data) // 2])
    with pytest.raises(ValueError, match="not a readable qdots state file"):
        qdots.load(saved)


def test_corrupted_bytes_are_a_clear_error(saved):
    data = bytearray(saved.read_bytes())
    data[100:400] = b"\x00" * 300
    saved.write_bytes(bytes(data))
    with pytest.raises(ValueError, match="not a readable qdots state file"):
        qdots.read_state(saved)


def test_other_files_are_clear_errors(tmp_path):
    text = tmp_path / "notes.npz"
    text.write_text("hello")
    with pytest.raises(ValueError, match="not a readable qdots state file"):
        qdots.load(text)
    other = tmp_path / "other.npz"
    np.savez(other, positions=np.zeros((1, 2)))
    with pytest.raises(ValueError, match="no metadata"):
        qdots.load(other)
    with pytest.raises(FileNotFoundError, match="no such qdots state file"):
        qdots.load(tmp_path / "absent.npz")


def test_wrong_format_and_version(tmp_path, saved):
    with np.load(saved) as f:
        arrays = {k: f[k] for k in f.files}
    meta = json.loads(str(arrays.pop("metadata")))
    for change, message in [({"format": "gsd"}, "not a qdots state file"), ({"version": 99}, "version 99")]:
        bad = tmp_path / "bad.npz"
        np.savez(bad, metadata=np.array(json.dumps({**meta, **change})), **arrays)
        with pytest.raises(ValueError, match=message):
            qdots.load(bad)


def test_invalid_saved_board_is_reported(tmp_path, saved):
    with np.load(saved) as f:
        arrays = {k: f[k] for k in f.files}
    arrays["radii"] = -arrays["radii"]
    bad = tmp_path / "bad.npz"
    np.savez(bad, **arrays)
    with pytest.raises(ValueError, match=r"the saved board is invalid: radii\[0\]"):
        qdots.load(bad)


def test_zip_member_damage(tmp_path, saved):
    bad = tmp_path / "bad.npz"
    with zipfile.ZipFile(saved) as src, zipfile.ZipFile(bad, "w") as dst:
        for item in src.infolist():
            data = src.read(item.filename)
            dst.writestr(item, data[:-8] if item.filename == "positions.npy" else data)
    with pytest.raises(ValueError, match="not a readable qdots state file"):
        qdots.load(bad)


def rewrite_metadata(source, target, change):
    with np.load(source) as data:
        arrays = {k: data[k] for k in data.files}
    metadata = json.loads(str(arrays.pop("metadata")))
    metadata = change(metadata)
    with open(target, "wb") as stream:
        np.savez(stream, metadata=np.array(json.dumps(metadata)), **arrays)


@pytest.mark.parametrize("change, board_damaged", [
    (lambda m: [1, 2], True), (lambda m: None, True), (lambda m: 3, True), (lambda m: "text", True),
    (lambda m: {k: v for k, v in m.items() if k != "time"}, True), (lambda m: {**m, "time": None}, True),
    (lambda m: {**m, "time": float("nan")}, True), (lambda m: {**m, "closed": "no"}, True),
    (lambda m: {**m, "engine": {**m["engine"], "iterations": 2**62}}, True),
    (lambda m: {**m, "engine": {}}, True),
    (lambda m: {**m, "engine": {k: v for k, v in m["engine"].items() if k != "dt"}}, True),
    (lambda m: {**m, "collisions": {"dot_dot": 1, "sideways": 2, "dot_wall": 0, "sticking": 0}}, False),
    (lambda m: {**m, "rng": {"bit_generator": "PCG64", "state": "x"}}, False),
    (lambda m: {**m, "forces": [{"type": "Warp"}]}, False),
], ids=["list", "null", "number", "string", "no-time", "null-time", "nan-time", "closed-string", "huge-iterations",
        "empty-engine", "engine-without-dt",
        "collision-name", "bad-rng", "unknown-force"])
def test_damaged_state_metadata_is_a_one_line_error(tmp_path, capsys, good_state, change, board_damaged):
    """Resuming needs every field; a picture or an analysis needs the board only (and says when it is damaged)."""
    bad = tmp_path / "bad.npz"
    rewrite_metadata(good_state, bad, change)
    assert qdots_main(["resume", str(bad), "--seconds", "0.01"]) == 2
    one_line_error(capsys)
    for argv in (["render", str(bad)], ["analyze", str(bad)]):
        if board_damaged:
            assert qdots_main(argv) == 2
            one_line_error(capsys)
        else:
            assert qdots_main(argv) == 0


def test_arrays_renamed_and_complex_positions_are_refused(tmp_path, capsys, good_state):
    npy = tmp_path / "array.npz"
    np.save(tmp_path / "array.npy", np.zeros(3))
    (tmp_path / "array.npy").rename(npy)
    assert qdots_main(["render", str(npy)]) == 2
    one_line_error(capsys)
    with np.load(good_state) as data:
        arrays = {k: data[k] for k in data.files}
    arrays["positions"] = arrays["positions"] + 1j
    with open(tmp_path / "complex.npz", "wb") as stream:
        np.savez(stream, **arrays)
    assert qdots_main(["render", str(tmp_path / "complex.npz")]) == 2
    assert "real numbers" in one_line_error(capsys)
    with pytest.raises(ValueError, match="real numbers"):
        qdots.Scene(box=(100, 100), positions=[[30 + 1j, 50]], radii=[7.5])


# ---------------------------------------------------------------- add_dots
def test_add_dots_validates_against_the_board():
    sim = qdots.Simulation(qdots.Scene(box=(100, 100), positions=[[50, 50]], radii=[7.5]), [qdots.ThermalKicks()])
    with pytest.raises(ValueError, match="new dot 0 overlaps dot 0"):
        sim.add_dots([[55, 50]], [7.5])
    with pytest.raises(ValueError, match=r"positions\[0\] .* outside the box"):
        sim.add_dots([[98, 50]], [7.5])
    with pytest.raises(ValueError, match=r"radii\[1\] = -1.0"):
        sim.add_dots([[20, 20], [80, 80]], [5.0, -1.0])
    sim.add_dots([[20, 20], [80, 80]], [5.0, 6.0], masses=[2.0, 3.0])
    assert sim.n_dots == 3
    np.testing.assert_array_equal(sim.masses, [1.0, 2.0, 3.0])
    sim.run(0.1)  # forces were re-bound to three dots
    assert sim.state().positions.shape == (3, 2)


def test_add_dots_to_an_empty_board():
    sim = qdots.Simulation(qdots.Scene(box=(100, 100), positions=np.zeros((0, 2)), radii=[]),
                           [qdots.VanDerWaals(), qdots.ThermalKicks()])
    sim.run(0.01)
    sim.add_dots([[30, 50], [50, 50]], [7.5, 7.5])
    sim.run(0.05)
    assert sim.state().velocities[0, 0] != 0.0


def test_add_dots_respects_wall_segments():
    scene = qdots.Scene(box=(100, 100), positions=np.zeros((0, 2)), radii=[], segments=[[0, 50, 100, 50]])
    sim = qdots.Simulation(scene)
    with pytest.raises(ValueError, match=r"new dot 0 crosses wall segments\[0\]"):
        sim.add_dots([[30, 45]], [7.5])
    sim.add_dots([[30, 40]], [7.5])
    assert sim.n_dots == 1


# ---------------------------------------------------------------- state files of earlier versions
def test_a_state_file_of_0_1_with_center_gravity_resumes_the_same_run(tmp_path):
    # 0.1 wrote the force as "CenterGravity" with key "center": read as today's CentreGravity, no warning
    sim = busy_simulation(n=20)
    sim.forces = [*sim.forces, qdots.CentreGravity((110.0, 130.0), 40.0)]
    sim.run(0.02)
    path = qdots.save(sim, tmp_path / "today.npz")
    with np.load(path) as f:
        arrays = {k: f[k] for k in f.files}
    meta = json.loads(str(arrays.pop("metadata")))
    assert meta["forces"][-1] == {"type": "CentreGravity", "centre": [110.0, 130.0], "magnitude": 40.0}
    meta["forces"][-1] = {"type": "CenterGravity", "center": [110.0, 130.0], "magnitude": 40.0}
    old = tmp_path / "written_by_0_1.npz"
    np.savez(old, metadata=np.array(json.dumps(meta)), **arrays)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        resumed, expected = checkpoint.load(old), checkpoint.load(path)
    assert resumed.forces[-1].to_dict() == expected.forces[-1].to_dict()
    resumed.run(0.05)
    expected.run(0.05)
    assert_same_run(resumed, expected)


def test_the_python_api_takes_todays_force_names_only():
    with pytest.raises(ValueError, match="unknown force type 'CenterGravity'"):
        qdots.forces.force_from_dict({"type": "CenterGravity", "center": [1.0, 2.0], "magnitude": 1.0})
    assert not hasattr(qdots, "CenterGravity") and not hasattr(qdots.forces, "CenterGravity")


def test_a_state_whose_engine_table_is_empty_is_refused_naming_the_settings(tmp_path, capsys, good_state):
    bad = tmp_path / "bad.npz"
    rewrite_metadata(good_state, bad, lambda m: {**m, "engine": {}})
    assert qdots_main(["resume", str(bad), "--seconds", "0.01"]) == 2
    err = one_line_error(capsys)
    assert "engine has no 'dt', 'substeps'" in err and "the engine settings of the run that saved it" in err
    assert not (tmp_path / "bad-t0.01s").exists() and sorted(p.name for p in tmp_path.iterdir()) == ["bad.npz"]
