"""The benchmark harness keeps working: the report it writes, ``--only`` merging, the registration
list, and the Pareto rule; under ``-m slow``, the whole ``python -m benchmarks --quick`` (~3 minutes).
"""

import importlib
import json
import subprocess
import sys
from pathlib import Path

import pytest

from benchmarks import BENCHMARKS
from benchmarks.pareto import Point, dominates, verdict

ROOT = Path(__file__).resolve().parent.parent


def harness(*args, cwd=ROOT):
    return subprocess.run([sys.executable, "-m", "benchmarks", *args], cwd=cwd, capture_output=True, text=True,
                          timeout=900)


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
def test_the_whole_quick_run_writes_every_section(tmp_path):
    run = harness("--quick", "--out", str(tmp_path))
    assert run.returncode == 0, run.stderr[-3000:]
    check_report(tmp_path, BENCHMARKS)


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
