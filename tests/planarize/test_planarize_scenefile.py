"""planarize TOML scene files: round trips, defaults, named scenes and every error path."""

import numpy as np
import pytest
from helpers import refused_file

import planarize
from planarize import Continuum, Fast, Model, Reference
from planarize.io.scenefile import load_scene, save_scene, scene_from_toml, scene_to_toml
from planarize.scene import SCENES, PlanarizeScene, RunSettings, SurfaceSpec, get_scene

ALL = [*SCENES.values(), *(s.quick(0.5) for s in SCENES.values())]


@pytest.mark.parametrize("scene", ALL, ids=lambda s: s.name)
def test_every_named_scene_round_trips_through_a_file(tmp_path, scene):
    path = save_scene(scene, tmp_path / "scene.toml")
    assert load_scene(path) == scene
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scene.toml"]


def test_tricky_values_round_trip_exactly(tmp_path):
    np.save(tmp_path / "z.npy", np.ones((3, 3)))
    scenes = [
        PlanarizeScene('odd "name" \\ é', seed=7, surface=SurfaceSpec("random_roughness", {
            "size": 300.0, "scales": [[100.0, 0.1 + 0.2], [20.0, 1 / 3]], "refine": 2, "boundary": "periodic"}),
            run=RunSettings(thickness=1 / 3, step=0.1 + 0.2, k_exp=1.3, record=[0.0, 0.1, 1 / 3], snapshots=[],
                            distance="exact", volume="thesis"), engine=Fast(tolerance=1e-17)),
        PlanarizeScene("conformal", run=RunSettings(rule="conformal"), engine=Continuum(rtol=0.1 + 0.2)),
        PlanarizeScene("file", surface=SurfaceSpec("file", {"path": str(tmp_path / "z.npy"), "unit": "um",
                                                            "spacing": [0.5, 0.25], "level": True}),
                       engine="reference"),
        PlanarizeScene("tilt", surface=SurfaceSpec("tilted_plane", {"slope": [0.1, -0.3], "points": 4})),
    ]
    for scene in scenes:
        assert scene_from_toml(scene_to_toml(scene)) == scene


def test_defaults_come_from_the_scene_functions_and_build_the_thesis_surfaces():
    assert SurfaceSpec("hill").build() == planarize.surfaces.hill()
    assert SurfaceSpec("depression").build() == planarize.surfaces.depression()
    assert get_scene("ta").build_surface() == planarize.surfaces.random_roughness(seed=0)
    assert get_scene("ta").replace(seed=3).build_surface() == planarize.surfaces.random_roughness(seed=3)
    ta = get_scene("ta").run
    assert (ta.thickness, ta.step, ta.snapshots) == (200.0, 0.5, [0.0, 50.0, 100.0, 150.0, 200.0])
    assert scene_from_toml("") == PlanarizeScene()  # every key optional
    text = scene_to_toml(SCENES["hill"])
    for line in ('kind = "hill"', "refine = 4", "rtol = 0.02", "# metal height consumed per oxidation: nm, in (0, 1000]",
                 "[surface]", "[run]", "[engine]", 'kind = "continuum"'):
        assert line in text
    assert "tolerance" not in text  # the fast engine's setting, not this scene's engine's


def test_relative_file_paths_are_relative_to_the_scene_file(tmp_path):
    (tmp_path / "data").mkdir()
    surface = planarize.Surface(np.arange(12.0).reshape(3, 4), 2.0)
    planarize.io.save_heights(surface, tmp_path / "data" / "scan.csv")
    (tmp_path / "scene.toml").write_text('[surface]\nkind = "file"\npath = "data/scan.csv"\n')
    scene = load_scene(tmp_path / "scene.toml")
    assert scene.build_surface() == surface
    run = scene.replace(run={"thickness": 0.5, "step": 0.1}).anodize()
    assert run.thickness >= 0.5


def test_quick_scales_step_and_refinement():
    quick = SCENES["hill"].quick(0.5)
    assert quick.run.step == 0.02 and quick.surface.params["refine"] == 2 and quick.run.thickness == 1.0
    assert SCENES["ta"].quick(0.1).surface.params["refine"] == 1
    with pytest.raises(ValueError, match=r"quick fraction must be in \(0, 1\]"):
        SCENES["hill"].quick(0)


def test_scene_runs_with_overrides():
    run = SCENES["hill"].quick(0.25).anodize(thickness=0.3, record=3)
    assert run.parameters["rtol"] == 0.08 and run.initial.shape == (5, 5) and len(run.history["target_nm"]) == 4
    fast = SCENES["hill"].replace(engine="fast").quick(0.25).anodize(thickness=0.3, record=3)
    assert fast.parameters["step"] == 0.04 and fast.parameters["engine"] == "fast"
    assert SCENES["hill"].replace(engine="reference").engine == Reference()
    with pytest.raises(ValueError, match="engine.tolerance is a setting of the fast engine"):  # never silently dropped
        SCENES["hill"].replace(engine={"kind": "reference", "tolerance": 0.1})
    scene = SCENES["hill"].replace(engine={"kind": "fast", "interacting": "together", "tolerance": 0.02})
    assert scene.engine == Fast(tolerance=0.02, interacting="together")
    assert scene.replace(engine={"tolerance": 0.5}).engine == Fast(tolerance=0.5, interacting="together")
    assert SCENES["hill"].replace(engine={"rtol": 0.1}).engine == Continuum(rtol=0.1)
    assert scene.run.options()["model"] == Model(step=0.01, k_exp=2.3)


@pytest.mark.parametrize("text, match", [
    ("sed = 1", r"unknown key 'sed' \(allowed: name, seed, surface, run, engine\)"),
    ("seed = -1", r"seed must be an integer in \[0, .*got -1"),
    ("seed = 1.5", r"seed must be an integer, got 1.5"),
    ("name = 3", r"name must be a string"),
    ("surface = 3", r"surface must be a table"),
    ("[surface]\nkind = 'blob'", r"surface.kind must be one of 'hill'"),
    ("[surface]\npoints = 4", r"surface.points must be odd"),
    ("[surface]\npoints = 2.0", r"surface.points must be an integer in \[3, 4,097\], got 2.0"),
    ("[surface]\nrefine = 0", r"surface.refine must be an integer in \[1, 4,097\], got 0"),
    ("[surface]\nspacing = -1", r"surface.spacing must be in \(0, "),
    ("[surface]\nmethod = 'quad'", r"surface.method must be one of 'linear', 'cubic', got 'quad'"),
    ("[surface]\nslope = [1, 2]", r"unknown key 'surface.slope' \(allowed in \[surface\]: kind, base"),
    ("[surface]\nkind = 'tilted_plane'\nslope = [1]", r"surface.slope must be 2 numbers, got \[1\]"),
    ("[surface]\nkind = 'random_roughness'\nsize = 450", r"surface.size \(450 nm\) must be a whole number"),
    ("[surface]\nkind = 'random_roughness'\nscales = [1, 2]", r"surface.scales\[0\] must be 2 numbers \(nm\), got 1"),
    ("[surface]\nkind = 'file'", r"surface.path is required"),
    ("[surface]\nkind = 'file'\npath = 'x.npy'\nunit = 'furlong'", r"surface.unit must be one of 'nm', 'um'"),
    ("[surface]\nkind = 'file'\npath = 'x.npy'\nchannel = 1.5", r"surface.channel must be a channel number \(integer >= 0\) or a channel title"),
    ("[surface]\nkind = 'file'\npath = 'x.npy'\nmax_aspect = 0.5", r"surface.max_aspect must be >= 1"),
    ("[run]\nstep = -1", r"run.step must be in \(0, 1000\] nm, got -1.0"),
    ("[run]\nthickness = 'thick'", r"run.thickness must be a number"),
    ("[run]\nk_exp = 0.5", r"run.k_exp must be in \[1, 5\], got 0.5"),
    ("[engine]\nkind = 'gpu'", r"engine.kind must be one of 'continuum', 'fast', 'reference', 'matlab', got 'gpu'"),
    ("[run]\ndistance = 'far'", r"run.distance must be one of 'thesis', 'exact'"),
    ("[run]\nvolume = 'mean'", r"run.volume must be one of 'exact', 'thesis'"),
    ("[engine]\nkind = 'fast'\ntolerance = -1", r"engine.tolerance must be in \[0, "),
    ("[engine]\nkind = 'fast'\ninteracting = 'first'", r"engine.interacting must be one of 'wait', 'together'"),
    ("[engine]\ntolerance = 0.1", r"engine.tolerance is a setting of the fast engine, not of engine 'continuum'"),
    ("[engine]\nkind = 'fast'\nrtol = 0.1", r"engine.rtol is a setting of the continuum engine, not of engine 'fast'"),
    ("[engine]\nrtol = 0", r"engine.rtol must be in \[0.0001, 1\]"),
    ("[engine]\nkind = 'reference'\nrtol = 0.1", r"engine.rtol is a setting of the continuum engine"),
    ("[engine]\nkind = 'fast'\nthreads = 2", r"unknown key 'engine.threads' \(allowed in \[engine\]: kind, tolerance, "
                                             r"interacting\)"),
    ("engine = 'fast'", r"engine must be a table"),
    ("[run]\nrule = 'uniform'", r"run.rule must be one of 'thesis', 'conformal'"),
    ("[run]\nrule = 'conformal'\n[engine]\nkind = 'reference'", r"run.rule 'conformal' is computed by the continuum "
                                                              r"engine only, not by engine 'reference'"),
    ("[run]\nrtol = 0.1\n[engine]\nkind = 'continuum'", r"run.rtol: the engine and its settings are the \[engine\] "
                                                     r"table's: write it as engine.rtol"),
    ("[run]\nrecord = 0", r"run.record must be an integer in \[1, 100,000\]"),
    ("[run]\nrecord = 'all'", r"run.record must be a count n .* or a list of thicknesses .*, got \'all\'"),
    ("[run]\nsnapshots = [0, 5]", r"run.snapshots must hold numbers in \[0, 1\] nm"),
    ("[run]\nstpe = 1", r"unknown key 'run.stpe'"),
    ("[run\n", r"invalid TOML"),
])
def test_bad_scene_files_name_the_key(tmp_path, text, match):
    refused_file(load_scene, tmp_path / "bad.toml", text, match)


def test_missing_and_unreadable_scene_files(tmp_path):
    with pytest.raises(FileNotFoundError):
        load_scene(tmp_path / "absent.toml")
    refused_file(load_scene, tmp_path / "binary.toml", b"\xff\xfe", "cannot read the scene file")
    with pytest.raises(ValueError, match="unknown scene 'mountain'; built-in scenes: hill, depression, ta, tilted"):
        get_scene("mountain")


OLD_FILES = [  # [run] tables of files written before the [engine] table, and what they still read as
    ("[run]\nengine = 'fast'\ntolerance = 0.1\ninteracting = 'together'", Fast(tolerance=0.1, interacting="together")),
    ("[run]\nrtol = 0.05", Continuum(rtol=0.05)),
    ("[run]\nengine = 'reference'\nthickness = 0.5", Reference()),
]


@pytest.mark.parametrize("text, engine", OLD_FILES)
def test_files_with_the_engine_in_the_run_table_are_read_with_a_note(text, engine):
    with pytest.warns(FutureWarning, match=r"since 0.3 the engine and its settings are an \[engine\] table"):
        scene = scene_from_toml(text)
    assert scene.engine == engine
    assert scene_from_toml(scene_to_toml(scene)) == scene  # written again, it is a file of today (no warning)


@pytest.mark.parametrize("text, match", [
    ("[run]\nengine = 'gpu'", r"run.engine must be one of 'continuum', 'fast', 'reference', 'matlab', got 'gpu'"),
    ("[run]\ntolerance = 0.1", r"run.tolerance is a setting of the fast engine, not of engine 'continuum'"),
    ("[run]\nengine = 'fast'\nrtol = 0.1", r"run.rtol is a setting of the continuum engine, not of engine 'fast'"),
    ("[run]\nrtol = 0", r"run.rtol must be in \[0.0001, 1\]"),
])
def test_old_files_bad_engine_keys_are_named_as_the_file_wrote_them(text, match):
    with pytest.warns(FutureWarning), pytest.raises(ValueError, match=match):
        scene_from_toml(text)


def test_each_run_key_is_declared_once_where_it_is_checked():
    """The [run] and [engine] keys are the declarations `Model`, the engines and `anodize` check with, so a scene
    file, a `RunSettings` and a direct call refuse a value in the same words, and the file's comment states that
    bound."""
    from labrig.validate import InputError
    from planarize import anodize, surfaces
    from planarize.anodize import RUN_ARGUMENTS
    from planarize.engines import KIND, Continuum, Fast, engine_params
    from planarize.scene import RUN, RUN_PARAMS, SURFACE_KINDS

    assert RUN_PARAMS["k_exp"] is Model.PARAMS["k_exp"] and RUN_PARAMS["thickness"] is RUN_ARGUMENTS["thickness"]
    assert SURFACE_KINDS["bump"][1] is surfaces.BUMP
    assert engine_params("fast")["interacting"] is Fast.PARAMS["interacting"]
    assert engine_params("continuum") == {"kind": KIND, "rtol": Continuum.PARAMS["rtol"]}
    assert not set(RUN) & {"engine", "rtol", "tolerance", "interacting"}  # each engine's, in [engine]
    assert Continuum.PARAMS["rtol"].comment() in scene_to_toml(PlanarizeScene())
    for make in (lambda: Model(k_exp=9), lambda: RunSettings(k_exp=9), lambda: scene_from_toml("[run]\nk_exp = 9")):
        with pytest.raises(InputError, match=r"k_exp must be in \[1, 5\], got 9.0$"):
            make()
    with pytest.raises(InputError, match=r"^thickness must be in \[0, 1e6\] nm, got -1.0$"):
        anodize(surfaces.hill(), -1.0)
    with pytest.raises(InputError, match=r"^thickness must be in \[0, 1e6\] nm, got -1.0$"):
        RunSettings(thickness=-1.0)
    with pytest.raises(InputError, match=r"^points must be an integer in \[3, 4,097\], got 2$"):
        surfaces.bump(points=2)
    with pytest.raises(InputError, match=r"surface.points must be an integer in \[3, 4,097\], got 2$"):
        scene_from_toml("[surface]\npoints = 2")
