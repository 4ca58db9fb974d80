"""Every count a parameter implies is bounded before a run starts: a one-line error naming the key, the value
and the bound, never a run that loops for ever. ``qdots run`` refuses an experiment file out of range (or of the
wrong type) in one line before it writes anything."""

import re

import pytest
from helpers import refused_run

import qdots
from labrig.validate import InputError
from qdots.cli import main as qdots_main
from qdots.experiment import Deposition, Experiment
from qdots.forces.thermal import MAX_KICKS_PER_RUN, MAX_KICKS_PER_STEP
from qdots.io.experiment_file import experiment_from_toml

ONE_DOT = qdots.Scene(box=(100, 100), positions=[[50, 50]], radii=[5])


@pytest.mark.parametrize("interval", [1e-300, 1e-9, 5e-324])
def test_a_kick_interval_far_below_the_step_is_refused_in_a_file(interval):
    """Found by the fuzzer: ``interval = 1e-300`` looped once per kick, for ever (and ``1e-9`` for hours)."""
    text = f'[[forces]]\ntype = "ThermalKicks"\ninterval = {interval!r}\n'
    with pytest.raises(InputError, match=r"^<string>: forces\[0\]: ThermalKicks.interval = .* kicks per time step of 0.02 s, "
                                         r"more than the 1,000 allowed: use an interval >= 2e-5 s") as error:
        experiment_from_toml(text)
    assert "\n" not in str(error.value)


def test_the_bound_is_the_stated_count_of_kicks_per_step():
    dt = Experiment().engine.dt
    Experiment(forces=[qdots.ThermalKicks(interval=dt / MAX_KICKS_PER_STEP * 1.001)])  # just inside: accepted
    with pytest.raises(InputError, match="kicks per time step"):
        Experiment(forces=[qdots.ThermalKicks(interval=dt / MAX_KICKS_PER_STEP * 0.999)])


def test_kicks_per_run_are_bounded_by_the_run_length():
    with pytest.raises(InputError, match=f"kicks in a run of 100000 s, more than the {MAX_KICKS_PER_RUN:,}"):
        Experiment(forces=[qdots.ThermalKicks(interval=5e-5)], deposition=Deposition(n_dots=0, settle=1e5))
    Experiment(forces=[qdots.ThermalKicks(interval=5e-5)], deposition=Deposition(n_dots=0, settle=1e4))


def test_python_refuses_the_same_schedules_before_running():
    with pytest.raises(InputError, match="ThermalKicks.interval = 1e-09 s gives 2e\\+07 kicks per time step"):
        qdots.Simulation(ONE_DOT, [qdots.ThermalKicks(interval=1e-9)])
    sim = qdots.Simulation(ONE_DOT, [qdots.ThermalKicks(interval=1e-5)], dt=1e-3)
    with pytest.raises(InputError, match="kicks per time step of 0.05 s"):  # a longer step, the same interval
        sim.engine = sim.engine.replace(dt=0.05)
    assert sim.dt == 1e-3
    with pytest.raises(InputError, match="kicks per time step"):
        sim.forces = [qdots.ThermalKicks(interval=1e-9)]
    assert sim.forces[0].interval == 1e-5  # the refused forces did not replace the old ones
    sim.forces = []
    sim.forces = [qdots.ThermalKicks(interval=3e-6)]
    with pytest.raises(InputError, match="kicks in a run of 1e\\+06 s"):
        sim.run(1e6)
    assert sim.steps_taken == 0


class Recorder:
    def __init__(self, every=1, max_records=None):
        self.every, self.states = every, []
        if max_records is not None:
            self.max_records = max_records

    def write(self, state):
        self.states.append(state.time)


def test_a_writer_gets_no_more_states_than_it_takes():
    sim = qdots.Simulation(ONE_DOT, dt=0.01)
    writer = sim.attach(Recorder(every=2, max_records=5))
    sim.run(0.08)  # steps 0, 2, 4, 6, 8: five states
    assert len(writer.states) == 5
    with pytest.raises(InputError, match="Recorder would get 6 states .* more than the 5 it takes"):
        sim.run(0.02)
    assert sim.steps_taken == 8 and len(writer.states) == 5
    sim.run(0.01)  # step 9 writes nothing
    assert len(writer.states) == 5


def test_a_deposition_is_checked_as_one_run_before_the_first_dot():
    exp = Experiment(deposition=Deposition(n_dots=3, interval=0.04, settle=0.1), board=qdots.experiment.Board(80, 80))
    sim = qdots.experiment.build_simulation(exp)
    writer = sim.attach(Recorder(every=1, max_records=10))
    with pytest.raises(InputError, match="Recorder would get 12 states"):  # 3 x 2 + 5 steps of 20 ms
        qdots.experiment.populate(sim, exp)
    assert sim.n_dots == 0 and writer.states == []


def test_a_movie_takes_a_bounded_number_of_frames(tmp_path):
    from qdots.render import MovieWriter

    sim = qdots.Simulation(ONE_DOT, dt=0.1)
    movie = MovieWriter(tmp_path / "run.mp4", every=1)
    sim.attach(movie)
    with pytest.raises(InputError, match="MovieWriter would get 100,001 states .* more than the 100,000 it takes"):
        sim.run(10_000.0)
    movie.abort()
    assert sim.steps_taken == 0


# -- experiment files run from the command line -------------------------------------------------

@pytest.mark.parametrize("text, message", [
    ("[deposition]\nn_dots = 1000000000000", r"deposition.n_dots must be an integer in \[0, 1,000,000\]"),
    ("[deposition]\nsettle = 1e300", r"deposition.settle must be in \[0, 100000\] s"),
    ("[deposition]\nsettle = 1e308", r"deposition.settle"),
    ("[engine]\ndt = 1e9", r"engine.dt must be in \[1e-7, 0.1\] s"),
    ("[engine]\niterations = 4611686018427387904", r"engine.iterations must be an integer in \[1, 1,000\]"),
    ("[engine]\nspatial_hash = [10.0, 4611686018427387904]", r"spatial_hash count"),
    ("[engine]\nspatial_hash = [1e-300, 1]", r"engine.spatial_hash cell size must be in \[0.1, 1e6\] px, got 1e-300"),
    ("[deposition]\nmean_diameter = 1e-300", r"deposition.mean_diameter must be in \[0.01, 1e6\] px, got 1e-300"),
    ("[[forces]]\ntype = 'VanDerWaals'\nr0 = true", r"VanDerWaals.r0 must be a number"),
    ("[[forces]]\ntype = 'ThermalKicks'\ninterval = true", r"ThermalKicks.interval must be a number"),
    ("[[forces]]\ntype = 'Gravity'\nacceleration = ['1', '2']", r"Gravity.acceleration must be 2 numbers"),
    ("[board]\nclosed = 'no'", r"board.closed must be true or false"),
    ("name = ''", r"name must be a non-empty string"),
])
def test_experiment_files_out_of_range_are_one_line_errors(tmp_path, capsys, text, message):
    assert re.search(message, refused_run(qdots_main, tmp_path / "bad.toml", text, capsys))
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())
