"""One pattern for the engines: a settings class per engine that builds its backend, the engine protocol the
simulation drives, the pair scheme as the one owner of the van der Waals numerics, and the 0.2 names deprecated."""

import inspect
import re
import warnings
from pathlib import Path

import numpy as np
import pytest
from helpers import lone_dot

import qdots
from labrig.validate import InputError
from qdots.engine import ENGINES, Backend, Chipmunk, Event, PairScheme, engine_from_dict

PACKAGE = Path(qdots.__file__).resolve().parent


def film(engine=None) -> qdots.Simulation:
    positions = np.array([(x, y) for x in range(20, 140, 20) for y in range(20, 140, 20)], float)
    scene = qdots.Scene(box=(160.0, 160.0), positions=positions, radii=np.full(len(positions), 7.5),
                        velocities=np.random.default_rng(2).normal(0.0, 20.0, positions.shape))
    return qdots.Simulation(scene, [qdots.VanDerWaals(), qdots.ThermalKicks()], seed=3, engine=engine)


def protocol_members() -> list[str]:
    return [name for name in vars(Backend) if not name.startswith("_")] + list(Backend.__annotations__)


@pytest.mark.parametrize("kind", list(ENGINES))
def test_each_engine_builds_a_backend_with_every_member_of_the_protocol(kind):
    sim = film(ENGINES[kind]())
    sim.run(0.1)
    backend = sim.backend
    for name in protocol_members():
        assert hasattr(backend, name), (kind, name)
    for name, member in vars(Backend).items():
        if callable(member) and not name.startswith("_"):
            ours = inspect.signature(getattr(type(backend), name))
            assert list(ours.parameters) == list(inspect.signature(member).parameters), (kind, name)
    assert backend.settings is sim.engine  # handed over once, when built
    assert set(backend.diagnostics()) == {"chipmunk": {"last_substeps"}, "event": {"events", "capped_frames"}}[kind]
    assert all(isinstance(value, (int, float)) for value in backend.diagnostics().values())


def test_no_step_takes_the_settings_again_and_nothing_probes_an_engine():
    """The settings go to a backend when it is built (or retuned), not with every step; callers read what an
    engine counts from diagnostics(), not by probing its attributes."""
    assert list(inspect.signature(Backend.step).parameters) == ["self", "forces", "time", "rng"]
    probes = [path.relative_to(PACKAGE).as_posix() for path in PACKAGE.rglob("*.py")
              if "getattr(sim.engine" in path.read_text() or "getattr(sim.backend" in path.read_text()]
    assert probes == []


def test_the_simulation_knows_no_engine_specific_setting_and_van_der_waals_no_numerics():
    simulation = (PACKAGE / "simulation.py").read_text()
    for name in (*Chipmunk.PARAMS, *Event.PARAMS):
        if name != "dt":
            assert not re.search(rf"\.{name}\b", simulation), name  # no such attribute read
    vdw = (PACKAGE / "forces" / "vdw.py").read_text()
    for name in PairScheme.PARAMS:
        assert not re.search(rf"\b{name}\b", vdw), name  # not even named
    assert "FORCE_NUMERICS" not in simulation


def test_the_pair_scheme_is_typed_and_checked_where_the_forces_see_it():
    assert inspect.get_annotations(qdots.forces.StepContext, eval_str=True)["pairs"] is PairScheme
    assert Chipmunk(pair_skin=2.0, near_gap=3.0, far_interval=0.05).pairs == PairScheme(2.0, 3.0, 0.05)
    assert Event(pair_skin=2.0).pairs == PairScheme(pair_skin=2.0)  # every pair every frame
    with pytest.raises(InputError, match=r"near_gap must be in \(0, 2000\] px, got 0.0"):
        PairScheme(near_gap=0.0)
    assert not PairScheme().splits(30.0) and PairScheme(far_interval=0.02).splits(30.0)
    assert not PairScheme(near_gap=40.0, far_interval=0.02).splits(30.0)


def test_settings_switch_engines_keeping_what_they_share():
    chipmunk = Chipmunk(dt=0.01, iterations=9, pair_skin=3.0, tune_allocator=False)
    event = chipmunk.replace(kind="event", max_events=7)
    assert event == Event(dt=0.01, max_events=7, pair_skin=3.0, tune_allocator=False)
    assert event.replace(kind="chipmunk") == Chipmunk(dt=0.01, pair_skin=3.0, tune_allocator=False)
    assert engine_from_dict(event.to_dict()) == event and engine_from_dict({}) == Chipmunk()
    with pytest.raises(InputError, match=r"engine.kind must be one of 'chipmunk', 'event', got 'verlet'"):
        chipmunk.replace(kind="verlet")
    with pytest.raises(InputError, match=r"unknown event engine setting 'substeps' \(known: kind, dt, max_events"):
        engine_from_dict({"kind": "event", "substeps": 2})
    with pytest.raises(InputError, match="engine must be the settings of an engine"):
        qdots.Simulation(lone_dot(), engine={"dt": 0.01})


def test_new_settings_of_the_same_engine_are_applied_where_they_belong():
    sim = film()
    sim.run(0.1)
    force = sim.forces[0]
    space, board = sim.backend.space, sim.state()
    sim.engine = sim.engine.replace(iterations=12, dt=0.01)  # solver knobs and the step: on the live space
    assert sim.backend.space is space and space.iterations == 12 and sim.force_cache(force)
    sim.engine = sim.engine.replace(far_interval=0.02)  # another pair scheme: the forces' caches go
    assert sim.backend.space is space and sim.force_cache(force) == {}
    sim.run(0.05)
    sim.engine = sim.engine.replace(spatial_hash=(20.0, 1000))  # another spatial index: a new space, same board
    assert sim.backend.space is not space
    assert np.array_equal(sim.state().positions, sim.backend.read()[0])
    assert sim.time == pytest.approx(0.15) and board.n_dots == sim.n_dots


def test_the_names_of_0_2_still_work_for_one_release_and_say_so():
    with pytest.warns(DeprecationWarning, match=r"qdots.EngineSettings is deprecated since 0.3"):
        make = qdots.EngineSettings
    assert make(kind="event", dt=0.01) == Event(dt=0.01) and make() == Chipmunk()
    sim = film()
    with pytest.warns(DeprecationWarning, match=r"Simulation.settings is deprecated since 0.3 .* Simulation.engine"):
        assert sim.settings is sim.engine
    with pytest.warns(DeprecationWarning):
        sim.settings = Event()
    assert isinstance(sim.engine, Event)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        qdots.Chipmunk(), qdots.Simulation(lone_dot()).engine  # today's names warn nothing
