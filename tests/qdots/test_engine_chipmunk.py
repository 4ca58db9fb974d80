"""The Chipmunk adapter (`qdots.engine.pymunk_adapter`, `qdots.engine.bodies`): bulk reads and writes of the bodies
and direct stepping give pymunk's own numbers, it is the only module that touches pymunk's internals, an
untested pymunk runs on the public API, and the allocator is tuned only on request."""

from __future__ import annotations

import ast
import math
import os
import re
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import numpy as np
import pymunk
import pytest

import qdots
from qdots.engine import bodies as body_io
from qdots.engine import pymunk_adapter as chipmunk
from qdots.engine.bodies import BodyArrays
from qdots.engine.pymunk_adapter import advance, internals

ROOT = Path(__file__).resolve().parents[2]


# ---------------------------------------------------------------- bulk access to the bodies, direct stepping
def dots_space(n=40, seed=0):
    """A space with ``n`` free discs at random places and speeds (no walls), and their bodies."""
    rng = np.random.default_rng(seed)
    space = pymunk.Space()
    bodies = []
    for _ in range(n):
        body = pymunk.Body(float(rng.uniform(0.5, 2.0)), math.inf)
        body.position = tuple(rng.uniform(0.0, 200.0, 2))
        body.velocity = tuple(rng.normal(0.0, 30.0, 2))
        space.add(body, pymunk.Circle(body, float(rng.uniform(2.0, 6.0))))
        bodies.append(body)
    return space, bodies


def test_the_body_fields_are_found_in_chipmunks_memory():
    found = internals()
    assert found is not None, "pymunk's body layout changed: the step falls back to pymunk.batch"
    offsets = found.body_offsets
    assert len(set(offsets.tolist())) == 2 and all(offset % 8 == 0 for offset in offsets.tolist())


@pytest.mark.parametrize("direct", [True, False], ids=["direct", "pymunk.batch"])
def test_reads_and_velocity_changes_equal_pymunks_own_accessors(direct, monkeypatch):
    if not direct:
        monkeypatch.setattr(body_io, "internals", lambda: None)
    space, bodies = dots_space()
    io = BodyArrays(space, bodies)
    assert io.direct is direct
    space.step(0.01)  # positions and velocities as Chipmunk's integrator leaves them
    expected = np.array([(*b.position, *b.velocity) for b in bodies])
    rows = io.read_rows()
    assert np.array_equal(rows, expected) and not rows.flags.writeable
    dv = np.random.default_rng(1).normal(0.0, 100.0, (len(bodies), 2))
    io.add_velocities(dv, expected[:, 2:])
    assert np.array_equal([tuple(b.velocity) for b in bodies], expected[:, 2:] + dv)


def test_direct_velocity_changes_step_like_pymunks_velocity_setter():
    dv = np.random.default_rng(2).normal(0.0, 1e3, (40, 2))
    boards = []
    for direct in (True, False):
        space, bodies = dots_space(seed=3)
        if direct:
            io = BodyArrays(space, bodies)
            io.add_velocities(dv, io.read()[1])
        else:
            for body, change in zip(bodies, dv):
                body.velocity = tuple(np.asarray(body.velocity) + change)
        space.step(0.01)
        boards.append(np.array([(*b.position, *b.velocity) for b in bodies]))
    assert np.array_equal(*boards)


def test_direct_chipmunk_steps_equal_pymunks_step():
    boards = []
    for direct in (True, False):
        space, bodies = dots_space(seed=4)
        space.step(1e-3)  # clears what pymunk checks on new bodies
        if direct:
            advance(space, 1e-3, 50)
        else:
            for _ in range(50):
                space.step(1e-3)
        boards.append(np.array([(*b.position, *b.velocity) for b in bodies]))
    assert np.array_equal(*boards)


def test_a_space_with_pending_python_work_steps_through_pymunk():
    space, bodies = dots_space(n=3, seed=5)
    ran = []
    space.add_post_step_callback(lambda s, key: ran.append(key), "probe")
    advance(space, 1e-3, 2)
    assert ran == ["probe"]


def test_a_run_is_the_same_through_pymunk_batch(monkeypatch):
    def film(direct):
        rng = np.random.default_rng(6)
        grid = np.array([(x, y) for x in range(20, 200, 20) for y in range(20, 200, 20)], float)
        scene = qdots.Scene(box=(220, 220), positions=grid, radii=np.full(len(grid), 7.5),
                            velocities=rng.normal(0, 20, grid.shape))
        sim = qdots.Simulation(scene, [qdots.VanDerWaals(), qdots.ThermalKicks()], seed=6)
        assert sim.backend.io.direct is direct
        sim.run(0.5)
        return sim.state()

    direct = film(True)
    monkeypatch.setattr(body_io, "internals", lambda: None)  # the bulk reads and writes alone fall back
    fallback = film(False)
    assert np.array_equal(direct.positions, fallback.positions)
    assert np.array_equal(direct.velocities, fallback.velocities)


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
    adapter = package / "engine" / "pymunk_adapter.py"
    sources = sorted(package.rglob("*.py"))
    assert adapter in sources and len(sources) > 30
    used = {path.relative_to(package).as_posix(): pymunk_internals_used(path) for path in sources}
    assert used.pop("engine/pymunk_adapter.py")  # the scan sees the adapter's own uses
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


# ---------------------------------------------------------------- an untested pymunk: the public API, one warning
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
    assert direct.backend.io.direct and direct.collisions.compiled
    assert expected["dot_dot"] >= 3 and expected["dot_wall"] >= 3 and expected["draws"] >= 1

    monkeypatch.setattr(pymunk, "version", "7.9.0")
    chipmunk.internals.cache_clear()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        public, got = small_collider()
    runtime = [w for w in caught if issubclass(w.category, RuntimeWarning)]
    assert len(runtime) == 1, [str(w.message) for w in runtime]
    assert "pymunk 7.9.0 is not a tested version" in str(runtime[0].message)
    assert public.backend.io.direct is False and public.collisions.compiled is False
    for key, value in expected.items():
        np.testing.assert_array_equal(got[key], value, err_msg=key)


def test_tested_pymunk_versions():
    for major, minor in chipmunk.TESTED_PYMUNK:
        assert chipmunk.pymunk_tested(f"{major}.{minor}.0") and chipmunk.pymunk_tested(f"{major}.{minor}.12")
    assert not chipmunk.pymunk_tested("7.9.0") and not chipmunk.pymunk_tested("6.3.0")
    assert not chipmunk.pymunk_tested("seven") and not chipmunk.pymunk_tested("7")


def test_the_pymunk_pin_is_the_tested_range():
    """pyproject pins the pymunk versions the adapter was tested with; others run on the public API."""
    text = (ROOT / "pyproject.toml").read_text()
    low, high = re.search(r'"pymunk>=(\d+\.\d+),<(\d+\.\d+)"', text).groups()
    assert chipmunk.pymunk_tested(low + ".0") and not chipmunk.pymunk_tested(high + ".0")
    assert chipmunk.pymunk_tested(pymunk.version)


# ---------------------------------------------------------------- the allocator: tuned only on request
ALLOCATOR_PROBE = """
import qdots
from qdots.engine.allocator import tune_allocator

assert tune_allocator.cache_info().misses == 0, "importing qdots tuned the allocator"
scene = qdots.Scene(box=(100.0, 100.0), positions=[[50.0, 50.0]], radii=[7.5])
qdots.Simulation(scene, engine=qdots.Chipmunk(tune_allocator=False)).step(2)
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
