"""The benchmark harness keeps working: the report it writes, ``--only`` merging, the registration
list, the settings every benchmark names, the marks of sections older than their code, the Pareto rule and the EMPS
strata read off hand-drawn labels; under ``-m slow``, the whole ``python -m benchmarks --quick`` within `QUICK_LIMIT`
(about 3 minutes measured on a 2-core machine), each benchmark within `QUICK_EACH`.
"""

import ast
import importlib
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import qdots
from benchmarks import BENCHMARKS, pinned
from benchmarks.__main__ import render
from benchmarks.pareto import Point, dominates, verdict
from benchmarks.staleness import CHIPMUNK_ENGINE, EVENT_ENGINE, is_stale, last_change, measured_paths

ROOT = Path(__file__).resolve().parent.parent
#: The shared TEM micrograph beside the project (`benchmarks.qdots_infer` infers from it).
TEM = ROOT.parent / "shared" / "data" / "micrographs" / "nanoparticle_film_tem.png"
#: Longest the whole quick run may take, and each benchmark's quick mode, s (measured: 172 s and at most 29 s).
QUICK_LIMIT, QUICK_EACH = 600, 120


def harness(*args, cwd=ROOT, timeout=900):
    return subprocess.run([sys.executable, "-m", "benchmarks", *args], cwd=cwd, capture_output=True, text=True,
                          timeout=timeout)


def check_report(tmp_path: Path, names: list[str]) -> dict:
    """The report of a quick run of ``names``: every section, headline (time and error) and figure."""
    report = (tmp_path / "performance.md").read_text()
    store = json.loads((tmp_path / "performance.json").read_text())
    assert list(store["sections"]) == names
    for name, section in store["sections"].items():
        assert f"## {name}:" in report and section["mode"] == "quick"
        for headline in section["headlines"]:  # time AND error, measured in the same run
            assert headline["time"].strip() and headline["error"].strip(), (name, headline)
        for figure in section["figures"]:
            assert (tmp_path / "figures" / f"{figure}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    for needle in ("## Headlines", "cores", "numpy", "scipy", "pymunk", "figures/qdots_scaling.png"):
        assert needle in report, needle
    # every table row of the scaling section has a time and an error column
    scaling = store["sections"]["engine_overhead"]["markdown"]
    assert "total ms/step" in scaling and "worst overlap" in scaling
    assert store["sections"]["engine_overhead"]["headlines"]
    return store


@pytest.mark.slow
def test_a_quick_run_writes_the_report_and_only_keeps_other_sections(tmp_path):
    names = ["engine_overhead", "analysis", "sweeps"]
    run = harness("--quick", "--only", "engine_overhead", "sweeps", "--out", str(tmp_path))
    assert run.returncode == 0, run.stderr[-3000:]
    before = check_report(tmp_path, ["engine_overhead", "sweeps"])["sections"]["engine_overhead"]

    again = harness("--quick", "--only", "analysis", "--out", str(tmp_path))
    assert again.returncode == 0, again.stderr[-3000:]
    store = json.loads((tmp_path / "performance.json").read_text())
    assert sorted(store["sections"]) == sorted(names)
    assert store["sections"]["engine_overhead"] == before  # kept, not re-run
    assert not list(tmp_path.glob(".*tmp*"))  # no temporary files left behind


@pytest.mark.slow
@pytest.mark.release
def test_the_whole_quick_run_writes_every_section_in_time(tmp_path):
    """Every benchmark's quick mode runs, within `QUICK_EACH` s each and `QUICK_LIMIT` s in all (a change of a default
    that stretched a benchmark would fail here: each names its settings, `benchmarks.pinned`)."""
    names = list(BENCHMARKS)
    if not TEM.exists():  # a clone without ../shared beside it: qdots_infer measures the shared micrograph
        names.remove("qdots_infer")
    only = () if names == list(BENCHMARKS) else ("--only", *names)
    run = harness("--quick", *only, "--out", str(tmp_path), timeout=QUICK_LIMIT)
    assert run.returncode == 0, run.stderr[-3000:]
    store = check_report(tmp_path, names)
    slow = {name: s["seconds"] for name, s in store["sections"].items() if s["seconds"] > QUICK_EACH}
    assert not slow, f"quick modes longer than {QUICK_EACH} s: {slow}"


def test_unknown_benchmark_is_a_one_line_error(tmp_path):
    run = harness("--only", "no_such_benchmark", "--out", str(tmp_path))
    assert run.returncode == 2
    assert "unknown benchmark 'no_such_benchmark'" in run.stderr
    assert not (tmp_path / "performance.md").exists()


def test_a_corrupt_report_store_is_refused_not_overwritten(tmp_path):
    (tmp_path / "performance.json").write_text("{not json")
    run = harness("--quick", "--only", "analysis", "--out", str(tmp_path))
    assert run.returncode == 2 and "cannot read the previous report data" in run.stderr
    assert (tmp_path / "performance.json").read_text() == "{not json"


@pytest.mark.parametrize("name", BENCHMARKS)
def test_registered_benchmarks_import_and_can_be_run(name):
    """The harness calls run(quick), or main([]) for a module that has no run (full mode only)."""
    module = importlib.import_module(f"benchmarks.{name}")
    assert module.__doc__, "its first line is the report's section title"
    assert callable(getattr(module, "run", None)) or callable(getattr(module, "main", None))


def test_pareto_rule():
    default = Point("default", time=1.0, error=1e-3, default=True)
    assert verdict([default, Point("slower, better", 2.0, 1e-4)]) == "on the front"
    assert verdict([default, Point("noise", 0.9, 1e-3)]) == "on the front"  # 10 % faster is timing noise
    assert dominates(Point("faster", 0.7, 1e-3), default)
    assert dominates(Point("as fast, 3x better", 1.1, 3e-4), default)
    assert "dominated by faster (0.70x time" in verdict([default, Point("faster", 0.7, 1e-3)])
    # errors at round-off count as equal, and so do errors within twice their combined standard error
    assert verdict([Point("d", 1.0, 1e-16, True), Point("o", 1.05, 1e-17)], floor=1e-12) == "on the front"
    noisy = Point("d", 1.0, 2e-5, True, error_se=1e-5)
    assert verdict([noisy, Point("o", 1.0, 2e-6, error_se=1e-6)]) == "on the front"
    assert verdict([noisy, Point("o", 1.0, 1e-8, error_se=1e-9)]) == "on the front"  # 2e-5 - 1e-8 < 2 SE
    assert verdict([Point("d", 1.0, 2e-5, True, error_se=2e-6), Point("o", 1.0, 1e-8)]).startswith("dominated")


def test_packing_differences_pair_runs_by_seed():
    """A setting run on fewer seeds than the reference is compared on the seeds both ran, seed by seed."""
    from benchmarks.fig2_2_realtime import METRICS, metric_differences

    def record(seed, value):
        return {"seed": seed, **{key: value for key, _ in METRICS}}

    reference = [record(seed, 10.0 * seed) for seed in range(1, 9)]
    setting = [record(seed, 10.0 * seed + offset) for seed, offset in [(3, 1.0), (1, 3.0), (2, 2.0)]]
    for mean, se in metric_differences(setting, reference):  # differences 3, 2, 1 after pairing by seed
        assert mean == pytest.approx(2.0) and se == pytest.approx(1.0 / 3.0 ** 0.5)


def _calls(tree: ast.AST):
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            func = node.func
            yield node, func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")


@pytest.mark.parametrize("path", sorted((ROOT / "benchmarks").glob("*.py")), ids=lambda p: p.name)
def test_every_benchmark_names_the_engine_settings_it_measures(path):
    """No simulation of a benchmark takes the library's defaults: each is given its engine (`benchmarks.pinned`),
    and only `benchmarks.pinned` makes engine settings from scratch."""
    tree = ast.parse(path.read_text())
    for call, name in _calls(tree):
        where = f"{path.name}:{call.lineno}"
        if name == "Simulation":
            assert any(k.arg == "engine" for k in call.keywords), f"{where}: Simulation without engine="
        if path.name != "pinned.py":
            assert name not in ("Chipmunk", "Event", "EngineSettings"), f"{where}: settings made from the defaults"
            if name == "replace" and any(k.arg == "kind" for k in call.keywords):
                raise AssertionError(f"{where}: an engine switched keeping the defaults of the other (replace(kind=))")


def test_pinned_settings_give_every_knob_and_say_which_defaults_moved(monkeypatch):
    with pytest.raises(ValueError, match="missing: substeps"):
        pinned.every_knob(qdots.Chipmunk, dt=0.02)
    assert pinned.chipmunk(iterations=10).iterations == 10 and pinned.event(max_events=5).dt == pinned.EVENT.dt
    monkeypatch.setitem(pinned.PINNED, "chipmunk", pinned.CHIPMUNK.replace(iterations=7))
    moved = [m for m in pinned.moved_defaults() if m.startswith("chipmunk.")]
    assert moved == [f"chipmunk.iterations = {qdots.Chipmunk().iterations!r} (7 measured)"]
    assert not pinned.is_library_default(pinned.PINNED["chipmunk"])


def git(repo: Path, *args, date: str = "2026-01-02T12:00:00+00:00"):
    env = {**os.environ, "GIT_AUTHOR_DATE": date, "GIT_COMMITTER_DATE": date, "GIT_AUTHOR_NAME": "t",
           "GIT_AUTHOR_EMAIL": "t@example.org", "GIT_COMMITTER_NAME": "t", "GIT_COMMITTER_EMAIL": "t@example.org"}
    subprocess.run(["git", *args], cwd=repo, env=env, check=True, capture_output=True, timeout=60)


def test_a_section_is_older_than_its_code_when_a_later_commit_touched_what_it_measures(tmp_path):
    git(tmp_path, "init", "-q")
    (tmp_path / "engine").mkdir()
    (tmp_path / "engine" / "a.py").write_text("x = 1\n")
    (tmp_path / "other.py").write_text("y = 1\n")
    git(tmp_path, "add", ".")
    git(tmp_path, "commit", "-q", "-m", "first", date="2026-01-02T12:00:00+01:00")
    (tmp_path / "other.py").write_text("y = 2\n")
    git(tmp_path, "commit", "-q", "-am", "other code", date="2026-01-05T12:00:00+00:00")
    changed = last_change(["engine"], tmp_path)
    assert changed == "2026-01-02T12:00:00+01:00"  # the engine's last commit, not the later one elsewhere
    assert is_stale("2026-01-02T10:59:00+00:00", changed)  # run before it (offsets compared)
    assert not is_stale("2026-01-02T11:01:00+00:00", changed)
    outside = tmp_path.parent / f"{tmp_path.name}-no-repo"
    outside.mkdir()
    assert last_change(["engine"], outside) is None and not is_stale("2020-01-01T00:00:00+00:00", None)


def test_every_benchmark_names_code_that_exists():
    for name in BENCHMARKS:
        paths = measured_paths(name)
        assert paths[0] == f"benchmarks/{name}.py" and len(paths) > 1, name
        assert all((ROOT / p).exists() for p in paths), (name, paths)
    engine = {p.relative_to(ROOT).as_posix() for p in (ROOT / "qdots" / "engine").glob("*.py")}
    assert engine == set(CHIPMUNK_ENGINE) | set(EVENT_ENGINE)  # a new engine module belongs to one or both


def test_the_report_marks_the_sections_older_than_their_code():
    section = {"title": "t", "mode": "full", "seconds": 1.0, "machine": {"date": "2026-01-01T00:00:00+00:00"},
               "markdown": "body", "headlines": [], "figures": []}
    store = {"machine": {"cpu": "c", "load": "0", "python": "3", "numpy": "1", "scipy": "1", "pymunk": "7",
                         "date": "2026-01-01T00:00:00+00:00", "commit": "abc"},
             "sections": {"analysis": dict(section), "lqe": dict(section)}}
    text = render(store, freshness=lambda name, date: "older than its code (changed 2026-02-01)" if name == "lqe"
                  else "")
    assert "| [lqe](#lqe) | full | 1 | 2026-01-01T00:00:00+00:00 | **older than its code (changed 2026-02-01)** |" \
        in text
    assert "| [analysis](#analysis) | full | 1 | 2026-01-01T00:00:00+00:00 | unchanged since |" in text
    assert "1 of 2 sections are older than the code they measure: lqe." in text
    assert text.count("This section is older than its code") == 1


def ellipse_labels(shape, centres, axes):
    """Regions 1 .. n: ellipses of half-axes ``axes`` (a, b) along x and y at ``centres`` (x, y)."""
    rows, cols = np.indices(shape)
    labels = np.zeros(shape, dtype=np.int64)
    for k, ((x, y), (a, b)) in enumerate(zip(centres, axes), start=1):
        labels[((cols + 0.5 - x) / a) ** 2 + ((rows + 0.5 - y) / b) ** 2 <= 1.0] = k
    return labels


def test_the_emps_strata_read_off_the_labels():
    """Round discs are a film to measure, ellipses of axis ratio 2 one to refuse; fewer than 10 whole particles, or
    particles cut by the edge, are neither."""
    from benchmarks.micrograph_emps import label_shapes, stratum

    centres = [(30 + 60 * i, 30 + 60 * j) for i in range(4) for j in range(3)]
    discs = label_shapes(ellipse_labels((200, 260), centres, [(15, 15)] * 12))
    assert discs["particles"] == 12 and abs(discs["diameter"] - 30) < 1 and discs["aspect"] < 1.05
    assert stratum(discs) == "round"
    rods = label_shapes(ellipse_labels((200, 260), centres, [(20, 10)] * 12))
    assert abs(rods["aspect"] - 2) < 0.1 and stratum(rods) == "not round"
    assert stratum(label_shapes(ellipse_labels((200, 260), centres[:9], [(15, 15)] * 9))) is None
    cut = label_shapes(ellipse_labels((200, 260), [(x - 30, y) for x, y in centres], [(15, 15)] * 12))
    assert cut["particles"] == 9  # the first column crosses the edge


def test_an_emps_file_that_is_not_the_manifests_is_not_kept(tmp_path, monkeypatch):
    """Fetching from a folder: a picture whose sha256 is not the manifest's is reported and not written."""
    from benchmarks import micrograph_emps

    monkeypatch.setenv("NANODISORDER_REAL_MICROGRAPHS", str(tmp_path / "cache"))
    first = micrograph_emps.manifest()["image"][0]["file"]
    (tmp_path / "clone" / "images").mkdir(parents=True)
    (tmp_path / "clone" / "images" / first).write_bytes(b"not the picture")
    done = dict(micrograph_emps.fetch(tmp_path / "clone"))
    assert done[first].startswith(f"failed: ValueError: {first}: sha256")
    assert not (micrograph_emps.folder() / first).exists()


def test_the_bar_manifest_holds_the_emps_pictures_and_the_verdict_reads_boxes():
    """Every picture of micrograph_emps is in the bars' manifest once, in its half; the second and third batches' are
    none of those nor of micrograph_real's nor of each other's, each with its sha256, half of them in each half; every
    drawn bar is a box wider
    than tall; a bar found is the drawn one when its middle lies on it and it covers most of it, and a piece of it or a
    box elsewhere is not."""
    from benchmarks import micrograph_bars, micrograph_emps
    from benchmarks.real_data import entries

    emps = {e["file"]: e["half"] for e in micrograph_emps.manifest()["image"]}
    bars = micrograph_bars.manifest()
    first = [e for e in bars if e.get("batch", 1) == 1]
    second = [e for e in bars if e.get("batch", 1) == 2]
    third = [e for e in bars if e.get("batch", 1) == 3]
    assert len(first) + len(second) + len(third) == len(bars) and len(second) == 80 and len(third) == 40
    assert sorted(e["file"] for e in first) == sorted(emps)
    assert all(e["half"] == emps[e["file"]] and e["drawn"] for e in first)
    real = {e["path"].rsplit("/", 1)[-1] for e in entries() if e.get("repo") == "by256/emps"}
    seen = set(emps) | real
    for batch in (second, third):
        files = {e["file"] for e in batch}
        assert len(files) == len(batch) and not files & seen
        seen |= files
        assert all(len(e["sha256"]) == 64 and e["drawn"] for e in batch)
        assert sum(e["half"] == "dev" for e in batch) == sum(e["half"] == "test" for e in batch) == len(batch) // 2
    assert all(x1 - x0 > y1 - y0 > 0 for x0, y0, x1, y1 in (e["bar"] for e in bars if "bar" in e))
    verdict, names = micrograph_bars.verdict, micrograph_bars.VERDICTS
    assert verdict([100, 200, 200, 210], (101, 202, 199, 208)) == names[0]
    assert verdict([100, 200, 200, 210], (101, 202, 150, 208)) == names[1]  # half of it
    assert verdict([100, 200, 200, 210], (10, 20, 110, 28)) == names[1]
    assert verdict([100, 200, 200, 210], None) == names[2]
    assert verdict(None, None) == names[3] and verdict(None, (1, 2, 50, 6)) == names[4]


def test_the_hand_line_profile_reads_a_textured_particles_background_outside_its_outline():
    """A textured particle (mesoporous silica on a development picture: 55-60 px across, its hand line profiles read
    19-39 px) holds light specks lighter than the dim gap to its neighbour, and the crest was taken there. Where the
    outline is known, the crest is sought beyond `CREST_INSIDE` of its radius: the 40 px disc reads 40 px again."""
    from benchmarks.real_data import CREST_INSIDE, half_depth_widths

    image = np.full((121, 121), 1.0)
    yy, xx = np.indices(image.shape)
    r = np.hypot(xx - 60.5, yy - 60.5)
    image[r < 20] = 0.0  # a dark disc 40 px across
    image[(r > 26) & (r < 40)] = 0.0  # its neighbours all around, past a dim gap 6 px wide
    image[(r > 20) & (r < 26)] = 0.5
    image[55:66, 45:48] = image[55:66, 73:76] = 0.9  # light specks inside it, on its row
    image[45:48, 55:66] = image[73:76, 55:66] = 0.9  # and on its column
    centre = np.array([[60.5, 60.5]])
    naive = half_depth_widths(image, centre, True, 33.0)[0]
    read = half_depth_widths(image, centre, True, 33.0, np.array([CREST_INSIDE * 20.0]))[0]
    assert not naive > 30.0  # the speck taken for the crest (or no line served)
    assert read == pytest.approx(40.0, abs=1.5)


def test_the_library_error_is_told_from_the_seed_noise():
    """`benchmarks.qdots_infer_limits.library_error`: sets whose learnt mean is off by a known spread (0.3, shared
    by the set's films) under seed noise of 0.5 give back 0.3, not the 0.35 their mean residuals spread by."""
    from scipy.stats import multivariate_normal

    from benchmarks.qdots_infer_limits import gaussian_log_density, library_error, seed_noise

    K = 6
    rng = np.random.default_rng(7)
    sets, offsets = [], {}
    for k in range(3000):
        theta = np.full(4, float(k))
        offsets[k] = rng.normal(0.0, 0.3, K)
        sets.append((theta, 0, np.hstack([offsets[k] + rng.normal(0.0, 0.5, (8, K)), np.zeros((8, 2))])))
    scale = (np.zeros(K), np.ones(K))
    error = library_error(sets, scale, lambda theta, model, x: np.zeros((len(x), K)))
    assert np.allclose(error, 0.3, atol=0.02), error
    assert np.allclose(seed_noise(sets, scale), 0.5, atol=0.01)
    assert np.allclose(library_error(sets, scale, lambda theta, model, x: np.tile(offsets[int(theta[0])], (len(x), 1))),
                       0.0, atol=0.07)  # the right mean: what is left is the variance's sampling error
    cov = np.eye(K) + 0.3 * np.ones((K, K))
    r = rng.normal(size=(5, K))
    assert np.allclose(gaussian_log_density(r, np.broadcast_to(cov, (5, K, K))),
                       multivariate_normal(np.zeros(K), cov).logpdf(r))


def test_the_limits_study_reads_the_shipped_films_as_the_posterior_does():
    """`benchmarks.qdots_infer_limits.film_arrays` and `film_sets` with the posterior's six summaries are
    `qdots.inference.library.training_arrays` and `replicate_groups` (they read other measures too)."""
    from benchmarks.qdots_infer_limits import film_arrays, film_sets
    from qdots.inference.forward import MEASURES
    from qdots.inference.library import replicate_groups, shipped_replicates, shipped_rows, training_arrays

    rows = shipped_rows()[:300]
    for ours, theirs in zip(film_arrays(rows), training_arrays(rows)):
        assert np.array_equal(np.asarray(ours), np.asarray(theirs))
    replicates = shipped_replicates()
    for (t1, m1, x1), (t2, m2, x2) in zip(film_sets(replicates), replicate_groups(replicates), strict=True):
        assert np.array_equal(t1, t2) and m1 == m2 and np.array_equal(x1, x2)
    theta, models, x, ids = film_arrays(rows, tuple(MEASURES))
    assert x.shape == (len(ids), len(MEASURES) + 2) and np.isfinite(x).all()
