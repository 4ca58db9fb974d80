"""TOML experiment (scene) files: round trips, the text written, defaults, every error path, and files written by
earlier releases."""

import dataclasses
import inspect
import re
import warnings

import pytest
from helpers import refused_file

import qdots
from labrig.tomlfile import tomllib
from qdots.cli.sweep import ExperimentRunner
from qdots.engine import ENGINES, Chipmunk, Event
from qdots.experiment import Board, Deposition, Experiment
from qdots.forces import FORCE_TYPES, thesis_offset
from qdots.io import experiment_file
from qdots.io.experiment_file import (
    TABLES,
    experiment_from_toml,
    experiment_to_toml,
    load_experiment,
    save_experiment,
    table_params,
)
from qdots.presets import PRESETS, get_preset

ALL_PRESET_RUNS = [exp for name in PRESETS for exp in (*PRESETS[name], *get_preset(name, quick=True))]


# -- round trips ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("exp", ALL_PRESET_RUNS, ids=lambda e: e.name)
def test_every_preset_round_trips_through_a_file(tmp_path, exp):
    path = save_experiment(exp, tmp_path / "scene.toml")
    assert load_experiment(path) == exp
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scene.toml"]  # no temporary left behind


def test_floats_and_optional_engine_settings_round_trip_exactly():
    exp = Experiment(
        name='tricky "name" \\ with\nnewline and é',
        board=Board(width=1 / 3 * 900, height=600.0, closed=False),
        deposition=Deposition(sigma=0.1 + 0.2, interval=1e-17 + 0.7, heavy_mass=2.0000000000000004),
        restitution=qdots.Restitution(mean=0.8123456789012345, wall=0.9, sticking_speed=0.0),
        engine=Chipmunk(dt=1e-3 / 3, substeps=3, iterations=25, collision_slop=1e-9,
                              collision_bias=0.123, spatial_hash=(22.5, 1000), threads=2),
        forces=(qdots.Langevin(gamma=0.7), qdots.CentreGravity((123.456, 0.1 + 0.2), 1e-300),
                qdots.Gravity((0.0, -9.81))),
    )
    back = experiment_from_toml(experiment_to_toml(exp))
    assert back == exp
    assert back.deposition.sigma == 0.30000000000000004 and back.engine.spatial_hash == (22.5, 1000)


def test_an_unset_setting_whose_default_is_set_round_trips_as_false():
    """Fixed sub-steps (``overlap_tolerance=None``) would read back as the adaptive default if the key
    were left out of the file: it is written ``overlap_tolerance = false``."""
    exp = Experiment(engine=Chipmunk(overlap_tolerance=None))
    text = experiment_to_toml(exp)
    assert "\noverlap_tolerance = false " in text and "# collision_bias (unset)" in text
    assert experiment_from_toml(text) == exp
    assert experiment_from_toml(experiment_to_toml(Experiment())).engine.overlap_tolerance == 0.005


def test_the_far_pass_round_trips_set_and_unset():
    """Every vdW pair every step (``far_interval=None``, the default since the step is the thesis's frame) reads
    back unset; a far pass for a shorter step reads back as set."""
    exp = Experiment(forces=(qdots.VanDerWaals(), qdots.ThermalKicks()))
    text = experiment_to_toml(exp)
    assert "# far_interval (unset)" in text and "# strength (unset)" in text
    assert experiment_from_toml(text) == exp and experiment_from_toml(text).engine.far_interval is None
    split = exp.replace(engine=Chipmunk(dt=2.5e-3, far_interval=0.02))
    back = experiment_from_toml(experiment_to_toml(split))
    assert back == split and back.engine.far_interval == 0.02


# -- the text written: every key with its unit and range -----------------------------------------------

def test_written_file_has_every_key_with_units():
    text = experiment_to_toml(PRESETS["fig2-2"][1])
    for line in ("sigma = 0.15", "# standard deviation of the diameter as a fraction of the mean: unitless, in [0, 1)",
                 "[board]", "[deposition]", "[restitution]", "[engine]", "[[forces]]", 'type = "VanDerWaals"',
                 f"dt = {Chipmunk().dt}", "# collision_bias (unset)", "# spatial_hash (unset)"):
        assert line in text, line
    assert "# board width: px, in (0, 1e6]" in text and "# simulated time after the last dot: s, in [0, 100000]" in text


#: How a comment states a unit: ``what: unit, range`` (a unit of the package or "unitless"), or lists the choices.
UNIT = re.compile(r": (px|px/s|px/s\^2|s|1/s|1/px|radii|mean radii|mean-dot masses|mean-dot mass px\^2/s\^2|unitless), "
                  r"|: one of |: true or false$|: text of at most ")
#: How a comment states the range: an interval, a lower bound, the choices, or the longest text.
RANGE = re.compile(r"\bin [\[(]-?[\d.e-]+, -?[\d.e,-]+[\])]|integer >= \d|: one of |: true or false$"
                   r"|: text of at most [\d,]+ characters")


def key_lines(text: str):
    """``(table, key, comment)`` of every key line of a saved experiment file (set or written unset), comment
    None when the line has none."""
    table = ""
    for line in text.splitlines()[text.splitlines().index(""):]:  # after the file's header comment
        if not line or line.startswith("["):
            table = line.strip("[]")
            continue
        head, _, comment = line.rpartition("  # ") if "  # " in line else (line, "", None)
        unset = re.fullmatch(r"# (\w+) \(unset\)\s*", head)
        if unset:
            yield table, unset.group(1), comment
            continue
        (key,) = tomllib.loads(head).keys()  # a whole `key = value`: the comment was split off where it starts
        yield table, key, comment


@pytest.mark.parametrize("exp", ALL_PRESET_RUNS, ids=lambda e: e.name)
def test_every_key_of_a_saved_preset_states_its_unit_and_range(exp):
    """near_gap, far_interval, min_gap, max_gap, offset, centre and each force's type once had no range (or no
    comment) in a saved file, though the README says the comments state every bound."""
    lines = list(key_lines(experiment_to_toml(exp)))
    for table, key, comment in lines:
        assert comment, f"[{table}] {key} has no comment"
        assert UNIT.search(comment), f"[{table}] {key}: no unit in {comment!r}"
        assert RANGE.search(comment), f"[{table}] {key}: no range in {comment!r}"
    keys = {(table, key) for table, key, _ in lines}
    tables = {name: table_params(getattr(exp, name)) for name in TABLES}
    assert {("", key) for key in Experiment.PARAMS} | {(name, key) for name, params in tables.items()
                                                       for key in params} <= keys
    assert len(lines) == len(Experiment.PARAMS) + sum(len(params) for params in tables.values()) + \
        sum(len(spec) for spec in exp.forces)  # every key of every table once, each force's type and parameters


def test_declarations_cover_every_parameter_and_the_file_module_restates_no_bound():
    assert list(Experiment.PARAMS) == ["name", "seed", "grating"]
    for cls in (Board, Deposition, qdots.Restitution, *ENGINES.values()):
        assert list(cls.PARAMS) == [f.name for f in dataclasses.fields(cls)], cls
    for name, cls in FORCE_TYPES.items():
        assert list(cls.PARAMS) == [p for p in inspect.signature(cls.__init__).parameters if p != "self"], name
    assert not [name for name in vars(experiment_file) if name.startswith("MAX_") or name.endswith("_RANGE")]


def test_a_bound_changed_in_its_declaration_changes_the_check_and_the_file_comment(tmp_path, monkeypatch):
    """The check of a value and the comment of its key come from one declaration: change the declared bound and
    both follow (a table's field, an engine setting, a force parameter)."""
    monkeypatch.setitem(Board.PARAMS, "width", dataclasses.replace(Board.PARAMS["width"], high=500.0))
    monkeypatch.setitem(Chipmunk.PARAMS, "near_gap", dataclasses.replace(Chipmunk.PARAMS["near_gap"], high=8.0, unit="px"))
    monkeypatch.setitem(qdots.Drag.PARAMS, "linear", dataclasses.replace(qdots.Drag.PARAMS["linear"], low_open=True))
    with pytest.raises(ValueError, match=r"^board.width must be in \(0, 500\] px, got 550.0$"):
        Board(width=550.0)
    with pytest.raises(ValueError, match=r"^near_gap must be in \(0, 8\] px, got 9.0$"):
        Chipmunk(near_gap=9.0)
    with pytest.raises(ValueError, match=r"^Drag.linear must be in \(0, 1e6\] 1/s, got 0.0$"):
        qdots.Drag(linear=0.0)
    exp = Experiment(board=Board(400.0, 400.0), forces=(qdots.Drag(),))
    text = experiment_to_toml(exp)
    assert "# board width: px, in (0, 500]" in text and "# board height: px, in (0, 1e6]" in text
    assert "pulled every step: px, in (0, 8]" in text and "# linear friction f1: 1/s, in (0, 1e6]" in text
    path = tmp_path / "wide.toml"
    refused_file(load_experiment, path, text.replace("width = 400.0", "width = 550.0"),
                 r"board.width must be in \(0, 500\] px, got 550.0")


# -- defaults ------------------------------------------------------------------------------------------

def test_missing_keys_take_defaults_and_ints_are_accepted_for_floats():
    assert experiment_from_toml("") == Experiment()
    exp = experiment_from_toml('seed = 9\n[board]\nwidth = 300\n[deposition]\nsigma = 0.1\n[[forces]]\ntype = "Drag"\n')
    assert exp == Experiment(seed=9, board=Board(width=300.0), deposition=Deposition(sigma=0.1),
                             forces=(qdots.Drag().to_dict(),))
    assert isinstance(exp.board.width, float)
    assert experiment_from_toml("forces = []").forces == ()


def test_scene_file_keeps_derived_vdw_defaults_unset():
    spec = qdots.VanDerWaals(r0=10.0).to_dict()
    assert spec["strength"] is None and spec["max_gap"] is None
    assert qdots.forces.force_from_dict(spec).max_gap == 20.0
    assert qdots.VanDerWaals(max_gap=12.0).to_dict()["max_gap"] == 12.0


# -- errors ---------------------------------------------------------------------------------------------

@pytest.mark.parametrize("text, message", [
    ("nmae = 'x'", r"unknown key 'nmae' \(allowed: name, seed, grating, board, deposition"),
    ("[deposition]\nsigmaa = 0.1", r"unknown key 'deposition.sigmaa' \(allowed in \[deposition\]: protocol, "),
    ("[engine]\nsubsteps = 2.5", r"engine.substeps must be an integer, got 2.5"),
    ("seed = true", r"seed must be an integer, got True"),
    ("[board]\nclosed = 1", r"board.closed must be true or false, got 1"),
    ("[deposition]\nprotocol = 3", r"deposition.protocol must be a string, got 3"),
    ("[engine]\nspatial_hash = [10.0, 2.5]", r"engine.spatial_hash must be a list \[number, integer\]"),
    ("board = 5", r"board must be a table \(\[board\]\), got 5"),
    ("[deposition]\nsigma = 1.5", r"deposition.sigma must be in \[0, 1\), got 1.5"),
    ("[deposition]\nn_dots = -3", r"deposition.n_dots must be an integer in \[0, 1,000,000\], got -3"),
    ("[board]\nheight = 0", r"board.height must be in \(0, 1e6\] px"),
    ("[restitution]\nmean = 1.2", r"restitution.mean must be in \[0, 1\], got 1.2"),
    ("[engine]\ndt = -0.001", r"engine.dt must be in \[1e-7, 0.1\] s, got -0.001"),
    ("[engine]\nthreads = 4", r"engine.threads must be one of 1, 2, got 4"),
    ("grating = 900.0", r"grating must be 0 \(none\) or in \(deposition.mean_diameter = 15, board.height = 600\)"),
    ("[[forces]]\ntype = 'Magnetic'", r"forces\[0\]: unknown force type 'Magnetic' \(known: CentreGravity, "),
    ("[[forces]]\ntype = 'Drag'\nlinaer = 0.1", r"forces\[0\]: Drag has no parameter 'linaer'"),
    ("[[forces]]\nlinear = 0.1", r"forces\[0\]: a force must be a table with a 'type' key"),
    ("[[forces]]\ntype = 'Drag'\nlinear = -1.0", r"forces\[0\]: Drag.linear must be in \[0, "),
    ("[[forces]]\ntype = 'VanDerWaals'\noffset = 0.1", r"forces\[0\]: VanDerWaals.offset \(0.1\) must be below min_gap"),
    ("[[forces]]\ntype = 'VanDerWaals'\noffset = -1e4", r"forces\[0\]: VanDerWaals.offset must be in \[-1000, 1000\] px"),
    ("[[forces]]\ntype = ['Drag']", r"forces\[0\]: unknown force type \['Drag'\] \(known: CentreGravity, "),
    ("forces = 3", r"forces must be an array of tables"),
])
def test_bad_files_raise_errors_naming_the_file_and_key(tmp_path, text, message):
    path = tmp_path / "bad.toml"
    assert refused_file(load_experiment, path, text, message).startswith(f"{path}: ")


def test_malformed_toml_names_the_file_and_the_toml_error(tmp_path):
    path = tmp_path / "broken.toml"
    path.write_text("[deposition\nsigma = 0.1\n")
    with pytest.raises(ValueError, match=r"broken.toml: invalid TOML: .*line 1"):
        load_experiment(path)
    path.write_bytes(b"name = '\xff'\n")
    with pytest.raises(ValueError, match=r"broken.toml: cannot read the experiment file"):
        load_experiment(path)


def test_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError, match=r"experiment file .*nothing.toml. does not exist"):
        load_experiment(tmp_path / "nothing.toml")


def test_failed_save_keeps_the_previous_file(tmp_path, monkeypatch):
    path = save_experiment(Experiment(seed=1), tmp_path / "scene.toml")
    before = path.read_text()
    monkeypatch.setattr("qdots.io.experiment_file.experiment_to_toml", lambda exp: (_ for _ in ()).throw(RuntimeError()))
    with pytest.raises(RuntimeError):
        save_experiment(Experiment(seed=2), path)
    assert path.read_text() == before and sorted(p.name for p in tmp_path.iterdir()) == ["scene.toml"]
    with pytest.raises(TypeError, match="exp must be a qdots.experiment.Experiment"):
        save_experiment({"seed": 1}, path)


# -- files written by earlier releases ------------------------------------------------------------------

def test_a_file_of_0_2_with_vdw_numerics_means_what_it_meant():
    """0.2 kept the pair list's knobs and a sticking speed in the VanDerWaals table: the knobs are read into the
    engine table, and a sticking speed other than the collision rule's as the proxy offset it gave."""
    old = ('[restitution]\nsticking_speed = 1.0\n'
           '[[forces]]\ntype = "VanDerWaals"\nskin = 3.0\nnear_gap = 6.0\nfar_interval = false\nsticking_speed = 2.0\n'
           '[[forces]]\ntype = "VanDerWaals"\nsticking_speed = 1.0\n')
    exp = experiment_from_toml(old)
    assert exp.engine == Chipmunk(pair_skin=3.0, near_gap=6.0, far_interval=None)
    assert exp.forces[0] == qdots.VanDerWaals(offset=thesis_offset(15.0, 0.1, 2.0)).to_dict()
    assert exp.forces[1] == qdots.VanDerWaals().to_dict()  # the rule's own sticking speed: nothing to keep
    assert experiment_from_toml(experiment_to_toml(exp)) == exp
    with pytest.raises(ValueError, match=r"pair_skin = 3.0 differs from engine.pair_skin = 6.0"):
        experiment_from_toml('[engine]\npair_skin = 6.0\n[[forces]]\ntype = "VanDerWaals"\nskin = 3.0\n')


OLD_CENTRAL_FILE = """# an experiment file as qdots 0.1 wrote it: American spellings
name = "central sigma=0"
seed = 154
[board]
width = 600.0
height = 600.0
[deposition]
protocol = "center"
n_dots = 500
interval = 0.5
settle = 15.0
[[forces]]
type = "VanDerWaals"
[[forces]]
type = "CenterGravity"
center = [310.0, 290.0]
magnitude = 750.0
[[forces]]
type = "Drag"
linear = 0.1
"""


def test_an_experiment_file_of_0_1_loads_with_the_same_meaning(tmp_path):
    path = tmp_path / "central.toml"
    path.write_text(OLD_CENTRAL_FILE)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # data translation, not a deprecated API: no warning
        exp = load_experiment(path)
    today = OLD_CENTRAL_FILE.replace('"center"', '"centre"').replace("CenterGravity", "CentreGravity") \
        .replace("center =", "centre =")
    assert exp == experiment_from_toml(today)
    assert exp.deposition.protocol == "centre" and exp.centre() == (310.0, 290.0)
    assert exp.forces[1] == qdots.CentreGravity((310.0, 290.0), 750.0).to_dict()
    # saved again, it is written in today's spelling
    text = experiment_to_toml(exp)
    assert 'protocol = "centre"' in text and 'type = "CentreGravity"' in text and "center" not in text


def test_a_sweep_over_0_1_spellings_runs_the_same_experiments():
    # a sweep's runs are read like experiment files: the same canonical parameters, hence the same run hashes
    runner = ExperimentRunner()
    old = {"deposition": {"protocol": "center", "n_dots": 10},
           "forces": [{"type": "CenterGravity", "center": [300.0, 300.0], "magnitude": 5.0}]}
    new = {"deposition": {"protocol": "centre", "n_dots": 10},
           "forces": [{"type": "CentreGravity", "centre": [300.0, 300.0], "magnitude": 5.0}]}
    assert runner.canonical(old) == runner.canonical(new)
    assert old["deposition"]["protocol"] == "center" and old["forces"][0]["type"] == "CenterGravity"  # not changed


@pytest.mark.parametrize("text, message", [
    # an old key beside its new spelling is not guessed at
    ('[[forces]]\ntype = "CenterGravity"\ncenter = [1, 2]\ncentre = [3, 4]', r"CentreGravity has no parameter 'center'"),
    # the old key with today's type is not today's spelling
    ('[[forces]]\ntype = "CentreGravity"\ncenter = [1, 2]', r"CentreGravity has no parameter 'center'"),
    ('[deposition]\nprotocol = "centre-ish"', r"deposition.protocol must be one of 'random', 'centre'"),
])
def test_only_the_spellings_of_0_1_are_translated(tmp_path, text, message):
    refused_file(load_experiment, tmp_path / "bad.toml", text, message)


def test_the_python_api_takes_todays_spellings_only():
    with pytest.raises(ValueError, match=r"deposition.protocol must be one of 'random', 'centre', got 'center'"):
        Deposition(protocol="center")
    with pytest.raises(ValueError, match=r"unknown preset 'center-gravity' \(known: .*centre-gravity"):
        get_preset("center-gravity")


def test_an_event_engine_file_holds_its_own_settings_and_one_key_switches_engines():
    exp = Experiment(engine=Event(dt=0.01, max_events=2500, buffer=1e-5))
    text = experiment_to_toml(exp)
    engine = text[text.index("[engine]"):text.index("[[forces]]")]
    assert 'kind = "event"' in engine and "max_events = 2500" in engine and "substeps" not in engine
    assert experiment_from_toml(text) == exp
    switched = experiment_from_toml(text.replace('kind = "event"', 'kind = "chipmunk"'))
    assert switched.engine == Chipmunk(dt=0.01)  # the shared settings kept; the event engine's checked, unread
