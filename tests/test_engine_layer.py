"""The engine layer (issue 42): the engine owns each run, the physics holds no run state, one module touches
pymunk's internals, an untested pymunk runs on its public API, and the allocator is tuned only on request."""

from __future__ import annotations

import ast
import os
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import numpy as np
import pymunk
import pytest

import qdots
from qdots.experiment import Experiment
from labrig.validate import InputError
from qdots.engine import chipmunk

ROOT = Path(__file__).resolve().parent.parent


# ---------------------------------------------------------------- one force object, several simulations
def film(n: int, seed: int) -> qdots.Scene:
    """``n`` dots of mixed sizes and masses on a square lattice at 17 px pitch, moving at ~30 px/s."""
    rng = np.random.default_rng(seed)
    side = int(np.ceil(np.sqrt(n)))
    positions = 20.0 + 17.0 * np.argwhere(np.ones((side, side)))[:n].astype(float)
    return qdots.Scene(box=(40.0 + 17.0 * side, 40.0 + 17.0 * side), positions=positions,
                       radii=rng.uniform(5.5, 8.0, n), masses=rng.uniform(0.5, 2.0, n),
                       velocities=rng.normal(0.0, 30.0, (n, 2)))


SCENES = (film(100, 1), film(4, 2))
STEPS = 200


def thermal_forces() -> list[qdots.Force]:
    return [qdots.VanDerWaals(), qdots.ThermalKicks(), qdots.Langevin(gamma=0.5)]


def simulations(forces_of) -> list[qdots.Simulation]:
    """A simulation of each of `SCENES` with the forces ``forces_of(k)`` (k: the scene's index)."""
    return [qdots.Simulation(scene, forces_of(k), seed=10 + k) for k, scene in enumerate(SCENES)]


def boards(sims) -> list[tuple]:
    return [(sim.state().positions, sim.state().velocities, sim.collisions.to_dict()) for sim in sims]


def assert_same_boards(got, expected) -> None:
    for (positions, velocities, counts), (positions0, velocities0, counts0) in zip(got, expected):
        np.testing.assert_array_equal(positions, positions0)
        np.testing.assert_array_equal(velocities, velocities0)
        assert counts == counts0


@pytest.fixture(scope="module")
def references():
    """Each scene run on its own, with its own fresh force objects."""
    sims = simulations(lambda k: thermal_forces())
    for sim in sims:
        sim.step(STEPS)
    assert sims[0].collisions.dot_dot > 20 and sims[0].force_cache(sims[0].forces[0])["pairs"].i.size
    return boards(sims)


def test_one_force_object_serves_several_simulations_at_once(references):
    """Interleaved steps of two different scenes through ONE VanDerWaals, ThermalKicks and Langevin object
    each: bit for bit the runs each scene makes with forces of its own (the force once cached the other
    scene's radii, and the run stopped with a RunawayError)."""
    shared = thermal_forces()
    sims = simulations(lambda k: shared)
    assert all(a is b for a, b in zip(sims[0].forces, sims[1].forces))
    for _ in range(STEPS):
        for sim in sims:
            sim.step()
    assert_same_boards(boards(sims), references)


def test_one_force_object_serves_several_simulations_in_turn(references):
    shared = thermal_forces()
    sims = simulations(lambda k: shared)
    for sim in sims:
        sim.step(STEPS)
    assert_same_boards(boards(sims), references)
    again = simulations(lambda k: shared)[0]  # and a later simulation of the first scene
    again.step(STEPS)
    assert_same_boards(boards([again]), references[:1])


# ---------------------------------------------------------------- one module reaches into pymunk
#: What only the Chipmunk adapter may use: pymunk's private attributes and modules, cffi's ``ffi`` and ``lib``.
PRIVATE_ATTRIBUTES = {"_space", "_body", "_chipmunk"}
PRIVATE_NAMES = {"ffi", "lib"}


def pymunk_internals_used(path: Path) -> list[str]:
    """Where the module at ``path`` reaches into pymunk: ``line: what``.

    An attribute ``._space``, ``._body`` or ``._chipmunk`` of anything but ``self`` (a class's own attribute
    of that name is its business), a name ``ffi`` or ``lib`` (and ``lib.<anything>``), an import of
    ``pymunk._chipmunk``, or one of those names as a string (``getattr(space, "_space")``).
    """
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Attribute) and node.attr in PRIVATE_ATTRIBUTES:
            if not (isinstance(node.value, ast.Name) and node.value.id == "self"):
                found.append(f"{node.lineno}: .{node.attr}")
        elif isinstance(node, ast.Name) and node.id in PRIVATE_NAMES:
            found.append(f"{node.lineno}: {node.id}")
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            modules = [alias.name for alias in node.names] if isinstance(node, ast.Import) else [node.module or ""]
            names = [alias.name for alias in node.names]
            if any("_chipmunk" in m for m in modules) or PRIVATE_NAMES & set(names):
                found.append(f"{node.lineno}: import {', '.join(modules)} {', '.join(names)}")
        elif isinstance(node, ast.Constant) and node.value in PRIVATE_ATTRIBUTES | {"pymunk._chipmunk"}:
            found.append(f"{node.lineno}: {node.value!r}")
    return found


def test_only_the_chipmunk_adapter_touches_pymunk_internals():
    package = Path(qdots.__file__).resolve().parent
    adapter = package / "engine" / "chipmunk.py"
    sources = sorted(package.rglob("*.py"))
    assert adapter in sources and len(sources) > 30
    used = {path.relative_to(package).as_posix(): pymunk_internals_used(path) for path in sources}
    assert used.pop("engine/chipmunk.py")  # the scan sees the adapter's own uses
    assert {name: where for name, where in used.items() if where} == {}


def test_the_scan_sees_each_way_of_reaching_in(tmp_path):
    module = tmp_path / "probe.py"
    module.write_text(textwrap.dedent("""
        from pymunk._chipmunk import ffi, lib
        import pymunk._chipmunk

        class Holder:
            def __init__(self, space):
                self._space = space  # a holder's own attribute: allowed

            def peek(self, space, body):
                return space._space, body._body, lib.cpSpaceStep, getattr(space, "_space")
    """))
    assert len(pymunk_internals_used(module)) == 6, pymunk_internals_used(module)


# ---------------------------------------------------------------- an untested pymunk: the public API
def small_collider() -> tuple[qdots.Simulation, dict]:
    """12 dots in a 120 px box with vdW and kicks at a fixed sub-step, run 0.5 s; (simulation, its board)."""
    rng = np.random.default_rng(3)
    positions = 20.0 + 26.0 * np.argwhere(np.ones((4, 3))).astype(float)
    scene = qdots.Scene(box=(120.0, 100.0), positions=positions, radii=np.full(12, 7.5),
                        velocities=rng.normal(0.0, 60.0, (12, 2)))
    sim = qdots.Simulation(scene, [qdots.VanDerWaals(), qdots.ThermalKicks()], seed=4, overlap_tolerance=None)
    sim.run(0.5)
    state = sim.state()
    return sim, {"positions": state.positions, "velocities": state.velocities, **sim.collisions.to_dict()}


def test_an_untested_pymunk_runs_on_the_public_api_with_one_warning(monkeypatch, request):
    request.addfinalizer(chipmunk.internals.cache_clear)  # the next test finds the real internals again
    if chipmunk.internals() is None:
        pytest.skip(f"pymunk {pymunk.version} is untested here: there are no internals to compare with")
    direct, expected = small_collider()
    assert direct.engine.io.direct and direct.collisions.compiled
    assert expected["dot_dot"] >= 3 and expected["dot_wall"] >= 3 and expected["draws"] >= 1

    monkeypatch.setattr(pymunk, "version", "7.9.0")
    chipmunk.internals.cache_clear()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        public, got = small_collider()
    runtime = [w for w in caught if issubclass(w.category, RuntimeWarning)]
    assert len(runtime) == 1, [str(w.message) for w in runtime]
    assert "pymunk 7.9.0 is not a tested version" in str(runtime[0].message)
    assert public.engine.io.direct is False and public.collisions.compiled is False
    for key, value in expected.items():
        np.testing.assert_array_equal(got[key], value, err_msg=key)


def test_tested_pymunk_versions():
    for major, minor in chipmunk.TESTED_PYMUNK:
        assert chipmunk.pymunk_tested(f"{major}.{minor}.0") and chipmunk.pymunk_tested(f"{major}.{minor}.12")
    assert not chipmunk.pymunk_tested("7.9.0") and not chipmunk.pymunk_tested("6.3.0")
    assert not chipmunk.pymunk_tested("seven") and not chipmunk.pymunk_tested("7")


# ---------------------------------------------------------------- the allocator: tuned only on request
ALLOCATOR_PROBE = """
import qdots
from qdots.engine.allocator import tune_allocator

assert tune_allocator.cache_info().misses == 0, "importing qdots tuned the allocator"
scene = qdots.Scene(box=(100.0, 100.0), positions=[[50.0, 50.0]], radii=[7.5])
qdots.Simulation(scene, engine=qdots.EngineSettings(tune_allocator=False)).step(2)
assert tune_allocator.cache_info().misses == 0, "a simulation that opted out tuned the allocator"
qdots.Simulation(scene).step(2)
info = tune_allocator.cache_info()
assert (info.misses, info.hits) == (1, 0), info
print("probed")
"""


def test_importing_qdots_leaves_the_allocator_alone_and_a_simulation_tunes_it_on_request():
    env = {key: value for key, value in os.environ.items() if key != "QDOTS_KEEP_MALLOC"}
    run = subprocess.run([sys.executable, "-c", ALLOCATOR_PROBE], cwd=ROOT, env=env, capture_output=True,
                         text=True, timeout=120)
    assert run.returncode == 0 and run.stdout.strip() == "probed", run.stderr[-3000:]


# ---------------------------------------------------------------- the sub-step count of a fixed step
@pytest.mark.parametrize("n_forces", [0, 1, 2, 3])
def test_a_fixed_step_takes_its_sub_steps_whatever_the_number_of_forces(n_forces):
    """At a fixed sub-step (``overlap_tolerance=None``) every step takes ``substeps`` sub-steps; forces that add
    nothing leave the run as it is without them."""
    scene = qdots.Scene(box=(200.0, 100.0), positions=[[60.0, 50.0], [140.0, 50.0]], radii=[7.5, 7.5],
                        velocities=[[80.0, 3.0], [-70.0, 0.0]])
    sims = [qdots.Simulation(scene, [qdots.Drag(0.0, 0.0) for _ in range(k)], seed=1, substeps=3,
                             overlap_tolerance=None) for k in (0, n_forces)]
    for sim in sims:
        sim.step(400)  # one impact and a few bounces
        assert (sim.substeps_taken, sim.engine.last_substeps) == (1200, 3)
    assert sims[1].collisions.to_dict() == sims[0].collisions.to_dict() and sims[0].collisions.dot_dot == 1
    np.testing.assert_array_equal(sims[1].state().positions, sims[0].state().positions)
    np.testing.assert_array_equal(sims[1].state().velocities, sims[0].state().velocities)


# ---------------------------------------------------------------- the sticking speed is the collision rule's
def test_a_rule_that_never_sticks_and_the_thesis_proxy():
    """The proxy's offset b derives from the rule's sticking speed, which may be 0 (an elastic gas); 0.2's force
    had its own, above 0. A van der Waals run under such a rule is refused in one line before it starts, or
    runs: it does not die inside a step. An offset given to the force does not depend on the rule."""
    scene = qdots.Scene(box=(100.0, 100.0), positions=[[30.0, 50.0], [60.0, 50.0]], radii=[7.5, 7.5])
    rule = qdots.Restitution(sticking_speed=0.0)
    with pytest.raises(InputError, match=r"^VanDerWaals derives the thesis proxy's offset b from "
                                         r"restitution.sticking_speed, which is 0"):
        qdots.Simulation(scene, [qdots.VanDerWaals()], restitution=rule, seed=0)
    sim = qdots.Simulation(scene, [qdots.VanDerWaals()], seed=0)
    with pytest.raises(InputError, match="restitution.sticking_speed"):
        sim.restitution = rule
    assert sim.restitution.sticking_speed == 1.0  # the refused rule did not replace the old one
    with pytest.raises(InputError, match=r"^forces\[0\]: VanDerWaals derives"):
        Experiment(restitution=rule)
    given = qdots.Simulation(scene, [qdots.VanDerWaals(offset=-5.0)], restitution=rule, seed=0)
    given.run(0.05)
    assert given.state().velocities[0, 0] > 0.0  # pulled toward the other dot


def test_the_pymunk_pin_is_the_tested_range():
    """pyproject pins the pymunk versions the adapter was tested with; others run on the public API."""
    import re

    text = (Path(__file__).parent.parent / "pyproject.toml").read_text()
    low, high = re.search(r'"pymunk>=(\d+\.\d+),<(\d+\.\d+)"', text).groups()
    assert chipmunk.pymunk_tested(low + ".0") and not chipmunk.pymunk_tested(high + ".0")
    assert chipmunk.pymunk_tested(pymunk.version)
