"""What a run produced always saves and loads back; earlier files are never lost; bad input is one line.

Every case of the reliability review (~400 bad or unusual inputs over every command and file type) that
failed is here, each with what it does now.
"""

import json
import os
import re
import signal
import subprocess
import sys
import textwrap
import time
import zipfile

import numpy as np
import pytest
from conftest import to_toml

import qdots
from planarize.cli import main as planarize_main
from qdots.cli import main as qdots_main

GRAVITY_SCENE = """
name = "grav"
[board]
width = 100.0
height = 100.0
[deposition]
n_dots = 12
interval = 0.0
settle = 3.0
[restitution]
wall = 0.0
[[forces]]
type = "Gravity"
"""


def one_line_error(capsys, prog="qdots"):
    err = capsys.readouterr().err.strip().split("\r")[-1]  # (after the progress bars, which also go to stderr)
    assert err.startswith(f"{prog}: error:") and "\n" not in err and "Traceback" not in err, err
    return err


def run_ok(main, argv, capsys):
    assert main(argv) == 0
    return capsys.readouterr()


def refused_run(main, path, text, capsys, prog="qdots"):
    """``PROG run`` of a file holding ``text`` (results into ``out`` beside it): exit status 2 and a one-line
    error, returned."""
    path.write_text(text)
    assert main(["run", str(path), "--out", str(path.parent / "out")]) == 2
    return one_line_error(capsys, prog)


# -- runs that finished are saved and load back ----------------------------------------------------

def test_a_board_overlapping_a_wall_after_a_run_saves_loads_renders_and_resumes_in_place(tmp_path, capsys):
    scene = tmp_path / "grav.toml"
    scene.write_text(GRAVITY_SCENE)
    out = tmp_path / "out"
    run_ok(qdots_main, ["run", str(scene), "--out", str(out)], capsys)
    state = qdots.read_state(out / "grav.npz")  # a dot sits 0.01 px into the inelastic floor: still loads
    assert state.n_dots == 12
    run_ok(qdots_main, ["render", str(out / "grav.npz")], capsys)
    before = (out / "grav.npz").read_bytes()
    run_ok(qdots_main, ["resume", str(out / "grav.npz"), "--seconds", "3"], capsys)  # in place
    assert (out / "grav.npz").read_bytes() != before
    assert qdots.load(out / "grav.npz").time == pytest.approx(6.0)
    # run again into the same directory: the good result is replaced by another good one
    run_ok(qdots_main, ["run", str(scene), "--out", str(out)], capsys)
    assert qdots.read_state(out / "grav.npz").time == pytest.approx(3.0)


def test_large_overlap_at_a_coarse_time_step_is_measured_and_warned_not_refused(tmp_path, capsys):
    # 60 dots under the thesis's centre gravity at its 20 ms frame, fixed sub-steps (false: the default
    # adaptive sub-steps would split the impacts): they overlap by ~30 % of a radius (measured)
    path = tmp_path / "coarse.toml"
    path.write_text(to_toml({"name": "coarse", "board": {"width": 200.0, "height": 200.0},
                             "deposition": {"n_dots": 60, "interval": 0.0, "settle": 1.0},
                             "engine": {"dt": 0.02, "overlap_tolerance": False},
                             "forces": [{"type": "CentreGravity", "centre": [100.0, 100.0]}]}))
    assert qdots_main(["run", str(path), "--out", str(tmp_path / "out")]) == 0
    captured = capsys.readouterr()
    state = qdots.read_state(tmp_path / "out" / "coarse.npz")
    assert qdots.load(tmp_path / "out" / "coarse.npz").settings.overlap_tolerance is None  # as the file said
    overlap = qdots.analysis.overlaps(state)[0]
    assert overlap > qdots.simulation.OVERLAP_WARNING  # measured and kept ...
    header, row = (tmp_path / "out" / "summary.csv").read_text().splitlines()[:2]
    assert float(row.split(",")[header.split(",").index("max_overlap_pct_radius")]) == pytest.approx(100 * overlap,
                                                                                                     rel=1e-6)
    assert "warning: coarse: dots overlap" in captured.err  # ... and said
    run_ok(qdots_main, ["render", str(tmp_path / "out" / "coarse.npz")], capsys)


def test_dots_that_leave_an_open_board_are_counted_and_the_board_loads(tmp_path, capsys):
    path = tmp_path / "open.toml"
    path.write_text(to_toml({"name": "open", "board": {"width": 100.0, "height": 100.0, "closed": False},
                             "deposition": {"n_dots": 10, "interval": 0.0, "settle": 20.0},
                             "forces": [{"type": "Gravity", "acceleration": [0.0, -200.0]}]}))
    assert qdots_main(["run", str(path), "--out", str(tmp_path / "out")]) == 0
    err = capsys.readouterr().err
    state = qdots.read_state(tmp_path / "out" / "open.npz")
    escaped = qdots.analysis.escaped(state)
    assert escaped > 0 and f"{escaped} of 10 dots have left the open board" in err
    assert f",{escaped}," in (tmp_path / "out" / "summary.csv").read_text()
    sim = qdots.load(tmp_path / "out" / "open.npz")
    sim.run(0.1)  # and goes on


def test_a_run_that_fails_late_leaves_the_earlier_files_whole(tmp_path, capsys, monkeypatch):
    scene = tmp_path / "grav.toml"
    scene.write_text(GRAVITY_SCENE)
    out = tmp_path / "out"
    run_ok(qdots_main, ["run", str(scene), "--out", str(out)], capsys)
    before = {p.name: p.read_bytes() for p in out.iterdir()}

    def fail(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(qdots.render, "save_png", fail)
    assert qdots_main(["run", str(scene), "--out", str(out), "--seed", "9"]) == 2
    one_line_error(capsys)
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before  # nothing replaced, no temporary left


def test_the_input_scene_file_is_never_written_over(tmp_path, capsys):
    scene = tmp_path / "grav.toml"
    scene.write_text(GRAVITY_SCENE)
    run_ok(qdots_main, ["run", str(scene), "--seed", "7", "--out", str(tmp_path)], capsys)
    assert scene.read_text() == GRAVITY_SCENE
    assert "seed = 7" in (tmp_path / "grav.ran.toml").read_text()
    hill = tmp_path / "hill_quick_0.25.toml"  # the name of the scene inside
    run_ok(planarize_main, ["scene", "hill", "--quick", "0.25", "--save", str(hill)], capsys)
    text = hill.read_text()
    run_ok(planarize_main, ["run", str(hill), "--engine", "reference", "--out", str(tmp_path)], capsys)
    assert hill.read_text() == text
    assert 'engine = "reference"' in (tmp_path / "hill_quick_0.25.ran.toml").read_text()


def test_stale_temporary_files_are_cleared_by_the_next_run(tmp_path, capsys):
    scene = tmp_path / "grav.toml"
    scene.write_text(GRAVITY_SCENE)
    out = tmp_path / "out"
    out.mkdir()
    stale, fresh = out / ".grav-0123abcd.tmp.npz", out / ".grav-4567cdef.tmp.npz"
    stale.write_bytes(b"partial")
    fresh.write_bytes(b"another run, still writing")
    old = time.time() - 2 * 3600
    os.utime(stale, (old, old))
    run_ok(qdots_main, ["run", str(scene), "--out", str(out)], capsys)
    assert not stale.exists() and fresh.exists()


# -- bounds before allocation, no loop without a bound -----------------------------------------------

@pytest.mark.parametrize("text, message", [
    ("[deposition]\nn_dots = 1000000000000", r"deposition.n_dots must be an integer in \[0, 1,000,000\]"),
    ("[deposition]\nsettle = 1e300", r"deposition.settle must be in \[0, 100000\] s"),
    ("[deposition]\nsettle = 1e308", r"deposition.settle"),
    ("[engine]\ndt = 1e9", r"engine.dt must be in \[1e-7, 0.1\] s"),
    ("[engine]\niterations = 4611686018427387904", r"engine.iterations must be an integer in \[1, 1,000\]"),
    ("[engine]\nspatial_hash = [10.0, 4611686018427387904]", r"spatial_hash count"),
    ("[[forces]]\ntype = 'VanDerWaals'\nr0 = true", r"VanDerWaals.r0 must be a number"),
    ("[[forces]]\ntype = 'ThermalKicks'\ninterval = true", r"ThermalKicks.interval must be a number"),
    ("[[forces]]\ntype = 'Gravity'\nacceleration = ['1', '2']", r"Gravity.acceleration must be 2 numbers"),
    ("[board]\nclosed = 'no'", r"board.closed must be true or false"),
    ("name = ''", r"name must be a non-empty string"),
])
def test_experiment_files_out_of_range_are_one_line_errors(tmp_path, capsys, text, message):
    assert re.search(message, refused_run(qdots_main, tmp_path / "bad.toml", text, capsys))
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())


def test_a_huge_seed_count_is_refused_before_anything_is_allocated(tmp_path, capsys):
    (tmp_path / "sweep.toml").write_text("seeds = 1000000000\n[base]\nname = 'x'\n")
    start = time.perf_counter()
    assert qdots_main(["sweep", str(tmp_path / "sweep.toml"), "--workers", "1"]) == 2
    assert "seeds must be an integer in [1, 100,000]" in one_line_error(capsys)
    assert time.perf_counter() - start < 5


@pytest.mark.parametrize("run_table, message", [
    ("k_exp = 1e100", r"run.k_exp must be in \[1, 5\]"),
    ("k_exp = 1e10", r"run.k_exp"),
    ("thickness = 0.1\nstep = 5.0", r"step \(5 nm\) must not exceed thickness \(0.1 nm\)"),
    ("record = []", r"run.record"),
    ("thickness = inf", r"run.thickness"),
    ("engine = 'reference'\ntolerance = 0.1", r"settings of the fast engine"),
])
def test_planarize_parameters_out_of_range_are_one_line_errors(tmp_path, capsys, run_table, message):
    error = refused_run(planarize_main, tmp_path / "bad.toml", f"[run]\n{run_table}\n", capsys, "planarize")
    assert re.search(message, error)


def test_an_empty_snapshot_list_runs_and_writes_its_files(tmp_path, capsys):
    path = tmp_path / "none.toml"
    path.write_text("name = 'none'\n[surface]\nrefine = 1\n[run]\nthickness = 0.2\nsnapshots = []\n")
    run_ok(planarize_main, ["run", str(path), "--out", str(tmp_path)], capsys)
    assert (tmp_path / "none.npz").exists() and not (tmp_path / "none_surfaces.png").exists()


def test_runaway_dots_are_reported_physically(tmp_path, capsys):
    text = to_toml({"deposition": {"n_dots": 5, "interval": 0.0, "settle": 1.0}, "engine": {"dt": 0.1},
                    "forces": [{"type": "Gravity", "acceleration": [0.0, -1e8]}]})
    assert "the dots left the model's range" in refused_run(qdots_main, tmp_path / "fast.toml", text, capsys)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="parent-death signal is Linux's")
def test_sweep_workers_exit_when_the_sweep_is_killed(tmp_path):
    script = tmp_path / "slow.py"
    script.write_text(textwrap.dedent("""
        import time
        from labrig.sweeps import Sweep, run_sweep

        def run_one(params):
            time.sleep(60)
            return {"y": params["x"]}

        if __name__ == "__main__":
            run_sweep(Sweep(base={"x": 0}, axes={"x": [1, 2, 3]}), run_one, "out", workers=2, progress=False)
    """))
    parent = subprocess.Popen([sys.executable, str(script)], cwd=tmp_path)
    children = []
    for _ in range(100):
        time.sleep(0.1)
        children = subprocess.run(["pgrep", "-P", str(parent.pid)], capture_output=True, text=True,
                                  timeout=30).stdout.split()
        if len(children) >= 2:
            break
    assert len(children) >= 2, "the pool did not start"
    parent.send_signal(signal.SIGKILL)
    parent.wait(timeout=30)
    deadline = time.time() + 10
    alive = children
    while alive and time.time() < deadline:
        time.sleep(0.2)
        alive = [c for c in alive if subprocess.run(["kill", "-0", c], capture_output=True, timeout=30).returncode == 0
                 and "Z" not in subprocess.run(["ps", "-o", "stat=", "-p", c], capture_output=True, text=True,
                                               timeout=30).stdout]
    assert not alive, f"orphaned workers still running: {alive}"


# -- damaged and foreign files: one line each --------------------------------------------------------

@pytest.fixture(scope="module")
def good_state(tmp_path_factory):
    path = tmp_path_factory.mktemp("state") / "good.npz"
    scene = qdots.Scene(box=(100, 100), positions=[[30, 50], [70, 50]], radii=[7.5, 7.5])
    sim = qdots.Simulation(scene, [qdots.ThermalKicks()], seed=1)
    sim.run(0.05)
    qdots.save(sim, path)
    return path


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
    (lambda m: {**m, "collisions": {"dot_dot": 1, "sideways": 2, "dot_wall": 0, "sticking": 0}}, False),
    (lambda m: {**m, "rng": {"bit_generator": "PCG64", "state": "x"}}, False),
    (lambda m: {**m, "forces": [{"type": "Warp"}]}, False),
], ids=["list", "null", "number", "string", "no-time", "null-time", "nan-time", "closed-string", "huge-iterations",
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


def test_height_maps_with_absurd_numbers_are_one_line_errors(tmp_path, capsys):
    cases = {
        "zero.csv": "# Width: 0 nm\n# Height: 1 nm\n# Value units: nm\n1,2\n3,4\n",
        "huge.xyz": "0 0 1\n0 1e308 1\n1e308 0 1\n1e308 1e308 1\n",
        "tall.xyz": "0 0 1\n0 1 1.8e19\n1 0 1\n1 1 1\n",
    }
    for name, text in cases.items():
        (tmp_path / name).write_text(text)
        assert planarize_main(["import", str(tmp_path / name), "--thickness", "1", "--unit", "nm"]) == 2
        one_line_error(capsys, "planarize")
    for name, array in (("u64.npy", np.full((3, 3), 18_000_000_000_000_000_000, dtype=np.uint64)),
                        ("dates.npy", np.zeros((3, 3), dtype="timedelta64[s]")), ("big.npy", np.full((3, 3), 1e300))):
        np.save(tmp_path / name, array)
        assert planarize_main(["import", str(tmp_path / name), "--thickness", "1", "--unit", "nm", "--spacing",
                               "1"]) == 2
        one_line_error(capsys, "planarize")
    np.save(tmp_path / "flat.npy", np.zeros((3, 3)))
    for spacing in ("1e300", "1e-300"):
        assert planarize_main(["import", str(tmp_path / "flat.npy"), "--thickness", "1", "--unit", "nm",
                               "--spacing", spacing, "--step", "0.1"]) == 2
        assert "spacing" in one_line_error(capsys, "planarize")


def test_gwyddion_fields_without_sizes_are_one_line_errors(tmp_path):
    gwyfile = pytest.importorskip("gwyfile")
    from planarize.io import load_heights

    for xres in (None, 0):
        field = gwyfile.objects.GwyDataField(np.zeros((3, 3)), xreal=1e-9, yreal=1e-9, si_unit_xy="m", si_unit_z="m")
        if xres is None:
            del field["xres"]
        else:
            field["xres"] = xres
        container = gwyfile.objects.GwyContainer()
        container["/0/data"] = field
        path = tmp_path / f"bad{xres}.gwy"
        container.tofile(str(path))
        with pytest.raises(ValueError, match="xres"):
            load_heights(path)


def test_damaged_run_files_are_one_line_errors(tmp_path):
    import planarize
    from planarize.io.results import load_run, save_run

    run = planarize.anodize(planarize.surfaces.hill(points=3, refine=1), 0.05, record=2)
    good = save_run(run, tmp_path / "run.npz")
    data = good.read_bytes()
    (tmp_path / "truncated.npz").write_bytes(data[: len(data) // 2])
    with zipfile.ZipFile(good) as archive:  # a byte of the metal heights (after its local header)
        info = archive.getinfo("metal.npy")
    local = data[info.header_offset:info.header_offset + 30]
    start = info.header_offset + 30 + int.from_bytes(local[26:28], "little") + int.from_bytes(local[28:30], "little")
    flipped = bytearray(data)
    flipped[start + info.file_size - 3] ^= 0xFF
    (tmp_path / "flipped.npz").write_bytes(bytes(flipped))
    for name in ("truncated.npz", "flipped.npz"):
        with pytest.raises(ValueError, match="run"):
            load_run(tmp_path / name)
    with np.load(good) as archive:
        arrays = {k: archive[k] for k in archive.files}
    metadata = json.loads(str(arrays["metadata"]))
    for name, change in (("list", lambda a: {**a, "metadata": np.array(json.dumps([1]))}),
                         ("shape", lambda a: {**a, "metal": np.zeros((2, 2))}),
                         ("spacing", lambda a: {**a, "metadata": np.array(json.dumps({**metadata, "spacing": "x"}))})):
        with open(tmp_path / f"{name}.npz", "wb") as stream:
            np.savez(stream, **change(arrays))
        with pytest.raises(ValueError, match="run"):
            load_run(tmp_path / f"{name}.npz")


def test_damaged_sweep_records_are_run_again_and_damaged_tables_are_one_line(tmp_path, capsys):
    from labrig.sweeps import Sweep, run_sweep

    sweep = Sweep(base={"x": 1.0}, axes={"x": [1.0, 2.0]})
    result = run_sweep(sweep, _square, tmp_path / "s", workers=1, progress=False)
    record = next((tmp_path / "s" / "runs").iterdir())
    data = json.loads(record.read_text())
    data["row"] = ["not", "a", "row"]
    record.write_text(json.dumps(data))
    again = run_sweep(sweep, _square, tmp_path / "s", workers=1, progress=False)
    assert again.ran == 1 and again.rows == [dict(r, wall_s=a["wall_s"]) for r, a in zip(result.rows, again.rows)]
    table = tmp_path / "s" / "table.csv"
    lines = table.read_text().splitlines()
    table.write_text("\n".join(lines[:-1] + [lines[-1][: len(lines[-1]) // 3]]) + "\n")  # truncated mid-row
    assert qdots_main(["sweep-plot", str(table), "--metric", "y", "--x", "x"]) == 2
    one_line_error(capsys)
    table.write_text("\n".join(lines) + "\n")
    assert qdots_main(["sweep-plot", str(table), "--metric", "status", "--x", "x"]) == 2
    assert "holds no numbers" in one_line_error(capsys)


def _square(params):
    return {"y": params["x"] ** 2}


def test_analyze_json_is_strict_json(tmp_path, capsys, good_state):
    text = run_ok(qdots_main, ["analyze", str(good_state), "--json"], capsys).out

    def refuse(constant):
        raise AssertionError(f"{constant} is not JSON")

    summary = json.loads(text, parse_constant=refuse)
    assert summary["n_dots"] == 2


def test_api_type_errors_name_the_field():
    scene = qdots.Scene(box=(100, 100), positions=[[50, 50]], radii=[7.5])
    for call, field in ((lambda: qdots.Restitution(mean="x"), "Restitution.mean"),
                        (lambda: qdots.Simulation(scene, collision_bias="x"), "collision_bias"),
                        (lambda: qdots.Simulation(scene, seed=-1), "seed"),
                        (lambda: qdots.Simulation(scene, dt="fast"), "dt"),
                        (lambda: qdots.Simulation(scene, pair_skin="x"), "pair_skin"),
                        (lambda: qdots.Scene(box=(100, 100), positions=[[50, 50]], radii=[7.5], closed=1), "closed")):
        with pytest.raises(ValueError, match=field):
            call()


def test_paths_that_are_not_files_are_said_to_be(tmp_path, capsys):
    assert qdots_main(["run", str(tmp_path)]) == 2
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
