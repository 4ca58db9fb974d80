"""Fuzzing every kind of file a person gives: accepted and run, or refused in one line naming the key.

Valid files are mutated at random (known keys and unknown ones; booleans, strings, lists, huge, tiny,
negative, non-finite numbers). Each result must be one of: accepted (and, when small, run to the end with
finite results), or refused through the command line with exit status 2 and one line ``PROG: error: ...``;
never a traceback, a hang, or a changed earlier file. A few examples per kind run by default; ``-m slow``
runs many more.
"""

import contextlib
import functools
import json
import signal
import string

import numpy as np
import pytest
from helpers import to_toml
from hypothesis import HealthCheck, Phase, example, given, settings
from hypothesis import strategies as st

import qdots
from labrig.validate import InputError
from planarize.cli import main as planarize_main
from planarize.recording import Stalled
from qdots.cli import main as qdots_main
from qdots.io.experiment_file import experiment_from_dict

FEW, MANY = 12, 60
#: CPU seconds one example may take: a file that makes a run loop for ever fails its test instead of stalling it.
EXAMPLE_CPU_SECONDS = 60

WEIRD = st.one_of(
    st.booleans(),
    st.integers(-2**70, 2**70),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0, -1, 1e-300, 1e300, 2**62, -0.0, 1e9, 0.5, 3]),
    st.text(alphabet=string.ascii_letters + " .-", max_size=6),
    st.lists(st.one_of(st.integers(-5, 5), st.floats(-1e3, 1e3), st.text(max_size=2)), max_size=3),
)

EXPERIMENT_KEYS = ["name", "seed", "grating", "board.width", "board.height", "board.closed", "deposition.protocol",
                   "deposition.n_dots", "deposition.mean_diameter", "deposition.sigma", "deposition.mass_model",
                   "deposition.heavy_mass", "deposition.interval", "deposition.settle", "deposition.max_tries",
                   "restitution.mean", "restitution.wall", "restitution.sticking_speed", "engine.dt",
                   "engine.substeps", "engine.iterations", "engine.collision_slop", "engine.collision_bias",
                   "engine.spatial_hash", "engine.threads", "engine.pair_skin", "engine.far_interval",
                   "forces.0.r0", "forces.0.min_gap", "forces.0.skin",
                   "forces.0.model", "forces.1.interval", "forces.1.scale", "forces.2.acceleration", "forces.0.type",
                   "board.colour", "deposition.sigmaa", "extra"]
SMALL_EXPERIMENT = {"name": "fuzz", "board": {"width": 80.0, "height": 80.0},
                    "deposition": {"n_dots": 4, "interval": 0.01, "settle": 0.05},
                    "forces": [{"type": "VanDerWaals"}, {"type": "ThermalKicks"}, {"type": "Gravity"}]}


def set_key(tree: dict, key: str, value) -> None:
    node = tree
    parts = key.split(".")
    for part, below in zip(parts[:-1], parts[1:]):
        # an earlier mutation may have made a table (or a list of tables) a value: make it a table again
        container = list if below.isdigit() else dict
        index = int(part) if isinstance(node, list) else part
        if isinstance(node, list):
            node.extend({} for _ in range(index + 1 - len(node)))
        if not isinstance(node[index] if isinstance(node, list) else node.get(index), container):
            node[index] = [{} for _ in range(3)] if container is list else {}
        node = node[index]
    last = parts[-1]
    if isinstance(node, list):
        node[int(last)] = value
    else:
        node[last] = value


def refused_in_one_line(capsys, prog: str) -> str:
    err = capsys.readouterr().err.strip().split("\r")[-1]
    assert err.startswith(f"{prog}: error:") and "\n" not in err and "Traceback" not in err, err
    return err


class ExampleTooLong(Exception):
    """An example used more than `EXAMPLE_CPU_SECONDS` of CPU time."""


@contextlib.contextmanager
def cpu_time_limit(seconds: float):
    """Raise `ExampleTooLong` in the block once the process has used ``seconds`` more CPU time (a virtual timer:
    the wall-clock alarm stays free for the per-test timeout)."""
    def stop(signum, frame):
        raise ExampleTooLong(f"the example used more than {seconds:g} s of CPU time: a run that does not end?")

    previous = signal.signal(signal.SIGVTALRM, stop)
    signal.setitimer(signal.ITIMER_VIRTUAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_VIRTUAL, 0)
        signal.signal(signal.SIGVTALRM, previous)


def fuzz_tests(check, *examples, **strategies):
    """Two tests of ``check(fixtures..., **drawn)`` on hypothesis draws from ``strategies``: ``FEW`` examples
    by default (drawn the same way every time) and ``MANY`` random ones under ``-m slow`` (the explicit
    ``examples`` in the default one). Each example gets `EXAMPLE_CPU_SECONDS`; a failure is reported as found,
    not shrunk (shrinking would re-run an example that does not end)."""
    @functools.wraps(check)
    def limited(*args, **kwargs):
        with cpu_time_limit(EXAMPLE_CPU_SECONDS):
            return check(*args, **kwargs)

    def test(max_examples, derandomize):
        return settings(max_examples=max_examples, deadline=None, derandomize=derandomize,
                        phases=(Phase.explicit, Phase.generate),
                        suppress_health_check=[HealthCheck.function_scoped_fixture])(given(**strategies)(limited))

    few = test(FEW, True)
    for drawn in examples:
        few = example(**drawn)(few)
    return few, pytest.mark.slow(test(MANY, False))


def snapshot(directory) -> dict:
    return {str(p.relative_to(directory)): p.read_bytes() for p in directory.rglob("*") if p.is_file()}


@pytest.fixture(scope="module")
def earlier(tmp_path_factory):
    """An output directory that holds a good result of every name the fuzzed runs use."""
    out = tmp_path_factory.mktemp("earlier")
    scene = out / "seed.toml"
    scene.write_text(to_toml(SMALL_EXPERIMENT))
    assert qdots_main(["run", str(scene), "--out", str(out)]) == 0
    scene.unlink()
    return out


def check_experiment_file(tmp_path, capsys, earlier, mutations) -> None:
    tree = json.loads(json.dumps(SMALL_EXPERIMENT))
    for key, value in mutations:
        set_key(tree, key, value)
    try:
        text = to_toml(tree)
    except ValueError:  # a value TOML cannot hold
        return
    path = tmp_path / "fuzz.toml"
    path.write_text(text)
    try:
        exp = experiment_from_dict(tree)
    except InputError:
        exp = None
    if exp is not None:
        steps = (exp.deposition.n_dots * exp.deposition.interval + exp.deposition.settle) / exp.engine.dt
        if steps > 2000 or exp.deposition.n_dots > 30 or exp.board.width * exp.board.height > 1e6:
            return  # accepted; too long to run here
    before = snapshot(earlier)
    status = qdots_main(["run", str(path), "--out", str(earlier)])
    if status == 2:
        refused_in_one_line(capsys, "qdots")
        assert snapshot(earlier) == before  # nothing of the earlier result was replaced
        return
    assert status == 0
    capsys.readouterr()
    stem = qdots.cli.commands.slug(exp.name)
    state = qdots.read_state(earlier / stem / f"{stem}.npz")
    assert np.isfinite(state.positions).all() and np.isfinite(state.velocities).all()


MUTATIONS = st.lists(st.tuples(st.sampled_from(EXPERIMENT_KEYS), WEIRD), min_size=1, max_size=3)


test_experiment_files, test_experiment_files_many = fuzz_tests(
    check_experiment_file,
    dict(mutations=[("forces.0.r0", False)]),  # found by CI: a key inside the list of forces
    dict(mutations=[("forces", 5), ("forces.1.scale", 2.0)]),  # a list made a value, then one of its tables
    dict(mutations=[("forces.1.interval", 1e-300)]),  # found by a user's run: a kick per 1e-300 s looped for ever
    dict(mutations=[("restitution.sticking_speed", 1e-300)]),  # found by the random test: b overflowed to -inf
    mutations=MUTATIONS)


# -- state files --------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def state_parts(tmp_path_factory):
    scene = qdots.Scene(box=(100, 100), positions=[[30, 50], [70, 50], [50, 20]], radii=[7.5, 7.5, 5.0])
    sim = qdots.Simulation(scene, [qdots.ThermalKicks(), qdots.VanDerWaals()], seed=1)
    sim.run(0.02)
    path = tmp_path_factory.mktemp("state") / "good.npz"
    qdots.save(sim, path)
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files}
    return json.loads(str(arrays.pop("metadata"))), arrays


ARRAY_CHANGES = st.sampled_from(["nan", "huge", "complex", "empty", "shape", "int", "bool", "text", "negative"])
METADATA_KEYS = ["time", "start_time", "steps_taken", "box", "closed", "restitution", "engine", "forces", "rng",
                 "collisions", "format", "version", "new"]


def changed_array(array: np.ndarray, how: str) -> np.ndarray:
    return {"nan": np.full_like(array, np.nan, dtype=float), "huge": np.full_like(array, 1e300, dtype=float),
            "complex": array + 1j, "empty": np.zeros((0,) + array.shape[1:]), "shape": np.zeros((7, 3)),
            "int": array.astype(np.int64), "bool": array.astype(bool), "text": np.full(array.shape, "x"),
            "negative": -np.abs(array) - 1}[how]


def check_state_file(tmp_path, capsys, state_parts, array_changes, metadata_changes) -> None:
    metadata, arrays = json.loads(json.dumps(state_parts[0])), dict(state_parts[1])
    for name, how in array_changes:
        arrays[name] = changed_array(state_parts[1][name], how)
    for key, value in metadata_changes:
        metadata[key] = value
    path = tmp_path / "fuzz.npz"
    with open(path, "wb") as stream:
        np.savez(stream, metadata=np.array(json.dumps(metadata)), **arrays)
    for argv in (["render", str(path), "--out", str(tmp_path / "fuzz.png")],
                 ["resume", str(path), "--seconds", "0.01", "--out", str(tmp_path / "out")]):
        status = qdots_main(argv)
        if status == 2:
            refused_in_one_line(capsys, "qdots")
        else:
            assert status == 0
            capsys.readouterr()


STATE_ARGS = dict(array_changes=st.lists(st.tuples(st.sampled_from(["positions", "velocities", "radii", "masses",
                                                                    "segments"]), ARRAY_CHANGES), max_size=2),
                  metadata_changes=st.lists(st.tuples(st.sampled_from(METADATA_KEYS), WEIRD), max_size=2))


test_state_files, test_state_files_many = fuzz_tests(check_state_file, **STATE_ARGS)


# -- height maps ---------------------------------------------------------------------------------------

CELLS = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**25, 10**25),
                  st.sampled_from(["x", "", "1e400", "-", "#", "1,5"]), st.floats(-5, 5))
GRIDS = st.lists(st.lists(CELLS, min_size=1, max_size=5), min_size=1, max_size=5)


def check_height_map(tmp_path, capsys, rows, suffix, header) -> None:
    path = tmp_path / f"fuzz{suffix}"
    if suffix == ".npy":
        try:
            array = np.array(rows)
        except ValueError:  # ragged
            return
        np.save(path, array)
    else:
        text = "\n".join((",".join(str(c) for c in row) if suffix == ".csv" else " ".join(str(c) for c in row))
                         for row in rows)
        path.write_text(header + text + "\n")
    argv = ["import", str(path), "--thickness", "0.5", "--unit", "nm", "--save", str(tmp_path / "imported.toml")]
    if suffix != ".xyz" and not header:
        argv += ["--spacing", "1"]
    status = planarize_main(argv)
    if status == 2:
        refused_in_one_line(capsys, "planarize")
        return
    assert status == 0
    capsys.readouterr()
    from planarize.io.scenefile import load_scene

    scene = load_scene(tmp_path / "imported.toml")
    surface = scene.build_surface()
    if surface.z.size <= 36 and scene.run.thickness / scene.run.step <= 1000:  # small enough to run
        try:
            run = scene.anodize()
        except Stalled as exc:  # far steeper than the grid resolves: a one-line refusal naming what to try
            assert "\n" not in str(exc) and "--engine fast" in str(exc)
            return
        assert np.isfinite(run.oxide.z).all() and np.isfinite(run.distances).all()


HEADERS = st.sampled_from(["", "# Width: 4 nm\n# Height: 4 nm\n# Value units: nm\n", "# Width: 0 nm\n# Height: 1 nm\n",
                           "# XY units: nm\n# Value units: nm\n", "# Width: 1e400 um\n# Height: 1 um\n"])
HEIGHT_ARGS = dict(rows=GRIDS, suffix=st.sampled_from([".csv", ".txt", ".xyz", ".npy"]), header=HEADERS)


#: Found by the random test: a 3 x 3 map whose heights reach 8e5 nm on a 1.3 nm grid stalls the continuum engine.
STEEP_MAP = dict(rows=[[838457, 3.917760261978877, 4.7283560223576], [838457, 3.917760261978877, 4.7283560223576],
                       [-174884, -0.5, -688065]], suffix=".txt", header="# Width: 4 nm\n# Height: 4 nm\n# Value units: nm\n")

test_height_maps, test_height_maps_many = fuzz_tests(check_height_map, STEEP_MAP, **HEIGHT_ARGS)


# -- sweep files ---------------------------------------------------------------------------------------

SWEEP_KEYS = ["seeds", "axes.run.k_exp", "axes.run.step", "axes.surface.refine", "axes.run.thickness",
              "output.dir", "output.state", "points", "base", "axes", "extra"]


def check_sweep_file(tmp_path, capsys, mutations) -> None:
    tree = {"base": "hill", "seeds": 1, "axes": {"run": {"k_exp": [2.0, 2.3]}}, "output": {"dir": "out"}}
    for key, value in mutations:
        set_key(tree, key, value)
    try:
        text = to_toml(tree)
    except ValueError:
        return
    path = tmp_path / "sweep.toml"
    path.write_text(text)
    from planarize.cli.sweep import AnodizeRunner, load_sweep

    try:
        sweep = load_sweep(path).sweep
        runs = sweep.runs(AnodizeRunner(quick=0.25).canonical)
    except InputError as exc:
        assert "\n" not in str(exc)
        assert planarize_main(["sweep", str(path), "--workers", "1", "--quick", "0.25"]) == 2
        refused_in_one_line(capsys, "planarize")
        return
    assert 1 <= len(runs) <= 100_000


SWEEP_ARGS = dict(mutations=st.lists(st.tuples(st.sampled_from(SWEEP_KEYS), WEIRD), min_size=1, max_size=3))


test_sweep_files, test_sweep_files_many = fuzz_tests(check_sweep_file, **SWEEP_ARGS)


def test_an_example_that_does_not_end_fails_in_bounded_time():
    with pytest.raises(ExampleTooLong, match="more than 0.2 s of CPU time"):
        with cpu_time_limit(0.2):
            while True:
                pass
    assert signal.getitimer(signal.ITIMER_VIRTUAL) == (0.0, 0.0)  # disarmed after the example


def test_the_checks_fail_on_a_traceback_or_a_long_message(tmp_path, capsys, earlier, monkeypatch):
    """The fuzzers' verdicts are not vacuous: a valid file is run, and a crash or a multi-line refusal fails them."""
    check_experiment_file(tmp_path, capsys, earlier, [])
    assert (earlier / "fuzz" / "fuzz.npz").exists()
    import sys

    def refuse_in_two_lines(argv):
        print("qdots: error: first\nsecond", file=sys.stderr)
        return 2

    monkeypatch.setattr(sys.modules[__name__], "qdots_main", refuse_in_two_lines)
    with pytest.raises(AssertionError):
        check_experiment_file(tmp_path, capsys, earlier, [("deposition.sigma", 2.0)])

    def crash(argv):
        raise KeyError("a bug")

    monkeypatch.setattr(sys.modules[__name__], "qdots_main", crash)
    with pytest.raises(KeyError):
        check_experiment_file(tmp_path, capsys, earlier, [])
