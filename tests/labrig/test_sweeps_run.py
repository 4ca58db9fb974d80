"""Running sweeps: resume after a kill, failures and crashed workers recorded, workers that end with a killed
sweep, damaged run records run again, the table, sweep-plot."""

import json
import math
import os
import signal
import subprocess
import sys
import textwrap
import time
import uuid
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from helpers import one_line_error

from labrig.sweeps import Sweep, read_table, run_sweep, save_sweep_plot, summarize
from qdots.cli import main as qdots_main


@dataclass(frozen=True)
class Toy:
    """y = 10 x + seed; logs every call as a file in ``log`` (calls from any process are counted)."""

    log: str
    fail: tuple = ()    # x values that always raise
    crash: tuple = ()   # x values that kill their worker process
    flaky: tuple = ()   # x values that raise on their first call only
    sleep: float = 0.0
    kind = "tests.toy"

    def canonical(self, params):
        return dict(params)

    def __call__(self, params, state_path=None):
        x, seed = params["x"], params["seed"]
        tag = f"{x}_{seed}"
        first = not list(Path(self.log).glob(f"{tag}_*"))
        (Path(self.log) / f"{tag}_{uuid.uuid4().hex}").touch()
        time.sleep(self.sleep)
        if x in self.crash:
            os._exit(3)
        if x in self.fail or (x in self.flaky and first):
            raise RuntimeError(f"no good at x = {x}")
        if state_path is not None:
            np.save(state_path.with_suffix(".tmp.npy"), np.array([x, seed]))
            os.replace(state_path.with_suffix(".tmp.npy"), state_path)
        return {"y": 10.0 * x + seed, "even": seed % 2 == 0}


def calls(log, x=None, seed=None):
    names = [p.name.rsplit("_", 1)[0] for p in Path(log).iterdir()]
    return sum(1 for n in names if (x is None or n.split("_")[0] == str(x)) and
               (seed is None or n.split("_")[1] == str(seed)))


SWEEP = Sweep(base={"x": 0.0, "seed": 0}, axes={"x": [1.0, 2.0, 3.0, 4.0]}, seeds=2)


@pytest.fixture
def log(tmp_path):
    path = tmp_path / "log"
    path.mkdir()
    return path


def test_table_has_every_run_in_order(tmp_path, log):
    result = run_sweep(SWEEP, Toy(str(log)), tmp_path / "out", workers=2, progress=False, state=True)
    assert (result.ran, result.skipped, result.failed) == (8, 0, 0)
    rows = result.rows
    assert [(r["x"], r["seed"]) for r in rows] == [(x, s) for x in (1.0, 2.0, 3.0, 4.0) for s in (0, 1)]
    assert all(r["y"] == 10 * r["x"] + r["seed"] and r["status"] == "ok" and r["attempts"] == 1 for r in rows)
    assert list(rows[0])[:4] == ["run", "status", "x", "seed"]
    assert read_table(result.table) == [{k: v for k, v in r.items()} for r in rows]  # CSV round trip is exact
    try:
        import pyarrow  # noqa: F401
    except ImportError:
        assert result.parquet is None
    else:
        assert read_table(result.parquet) == rows
    for row in rows:
        assert np.load(tmp_path / "out" / row["state_file"]).tolist() == [row["x"], row["seed"]]
        record = json.loads((tmp_path / "out" / "runs" / f"{row['run']}.json").read_text())
        assert record["params"] == {"x": row["x"], "seed": row["seed"]} and record["row"]["y"] == row["y"]


def test_rerun_skips_finished_runs_and_extends(tmp_path, log):
    small = Sweep(base={"x": 0.0, "seed": 0}, axes={"x": [1.0, 2.0]}, seeds=2)
    run_sweep(small, Toy(str(log)), tmp_path / "out", workers=1, progress=False)
    assert calls(log) == 4
    result = run_sweep(SWEEP, Toy(str(log)), tmp_path / "out", workers=2, progress=False)
    assert (result.ran, result.skipped) == (4, 4)
    assert calls(log) == 8 and all(calls(log, x, s) == 1 for x in (1.0, 2.0, 3.0, 4.0) for s in (0, 1))
    again = run_sweep(SWEEP, Toy(str(log)), tmp_path / "out", workers=2, progress=False)
    assert again.ran == 0 and calls(log) == 8
    strip = [{k: v for k, v in r.items() if k != "wall_s"} for r in again.rows]
    assert strip == [{k: v for k, v in r.items() if k != "wall_s"} for r in result.rows]
    # asking for states re-runs the runs that finished without one
    with_state = run_sweep(small, Toy(str(log)), tmp_path / "out", workers=1, progress=False, state=True)
    assert with_state.ran == 4 and calls(log) == 12


KILLED = """
import sys
import qdots.cli  # the packages before tests/ goes on the path: its folders labrig/ and qdots/ would hide them
from labrig.sweeps import run_sweep
sys.path[:0] = [{here!r}, {tests!r}]
from test_sweeps_run import SWEEP, Toy
run_sweep(SWEEP, Toy({log!r}, sleep=0.3), {out!r}, workers=1, progress=False)
"""


def run_records(out: Path) -> list[Path]:
    """The run records a sweep has finished in ``out``: not the hidden temporary of a write the kill cut short."""
    return [p for p in (out / "runs").glob("*.json") if not p.name.startswith(".")]


def test_killed_sweep_resumes_without_rerunning_finished_runs(tmp_path, log):
    out = tmp_path / "out"
    script = KILLED.format(here=str(Path(__file__).parent), tests=str(Path(__file__).parents[1]), log=str(log),
                           out=str(out))
    proc = subprocess.Popen([sys.executable, "-c", script])
    deadline = time.monotonic() + 60
    while len(run_records(out)) < 3 and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.02)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)
    finished = {p.stem for p in run_records(out)}
    assert 3 <= len(finished) < 8, "the sweep should have been killed part way"
    for path in run_records(out):  # every record is whole
        assert json.loads(path.read_text())["status"] == "ok"
    before = calls(log)
    result = run_sweep(SWEEP, Toy(str(log)), out, workers=2, progress=False)
    assert result.skipped == len(finished) and result.ran == 8 - len(finished)
    assert calls(log) - before == 8 - len(finished)  # finished runs did not run again
    assert [r["status"] for r in result.rows] == ["ok"] * 8
    assert {r["run"] for r in result.rows} >= finished


def test_a_failing_run_is_retried_once_then_recorded(tmp_path, log):
    result = run_sweep(SWEEP, Toy(str(log), fail=(2.0,), flaky=(3.0,)), tmp_path / "out", workers=2, progress=False)
    assert result.failed == 2 and result.ran == 8
    rows = {(r["x"], r["seed"]): r for r in result.rows}
    for seed in (0, 1):
        bad = rows[(2.0, seed)]
        assert bad["status"] == "failed" and bad["attempts"] == 2 and bad["y"] is None
        assert bad["error"] == "RuntimeError: no good at x = 2.0"
        assert calls(log, 2.0, seed) == 2
        record = json.loads((tmp_path / "out" / "runs" / f"{bad['run']}.json").read_text())
        assert "raise RuntimeError" in record["traceback"]
        flaky = rows[(3.0, seed)]
        assert flaky["status"] == "ok" and flaky["attempts"] == 2 and flaky["y"] == 30 + seed
    assert all(rows[(x, s)]["status"] == "ok" for x in (1.0, 4.0) for s in (0, 1))
    # failed runs are tried again when the sweep is run again
    again = run_sweep(SWEEP, Toy(str(log)), tmp_path / "out", workers=1, progress=False, retries=0)
    assert (again.ran, again.failed) == (2, 0)


def test_a_run_that_kills_its_worker_is_isolated_and_recorded(tmp_path, log):
    result = run_sweep(SWEEP, Toy(str(log), crash=(3.0,)), tmp_path / "out", workers=2, progress=False)
    rows = {(r["x"], r["seed"]): r for r in result.rows}
    for seed in (0, 1):
        bad = rows[(3.0, seed)]
        assert bad["status"] == "failed" and "worker process died" in bad["error"] and bad["attempts"] == 2
    assert [r["status"] for r in result.rows].count("ok") == 6  # the runs sharing the pool were not charged
    assert all(r["attempts"] == 1 for r in result.rows if r["status"] == "ok")


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


def test_plain_function_and_bad_rows(tmp_path):
    result = run_sweep(Sweep(base={"x": 1.0}), square, tmp_path / "a", workers=1, progress=False)
    assert result.rows[0]["y"] == 1.0
    bad = run_sweep(Sweep(base={"x": 1.0}), reserved_key, tmp_path / "b", workers=1, progress=False)
    assert "reserved" in bad.rows[0]["error"]
    with pytest.raises(ValueError, match="picklable"):
        run_sweep(Sweep(base={"x": 1.0}), lambda p: {"y": 1}, tmp_path / "c", workers=2, progress=False)
    with pytest.raises(ValueError, match=r"workers must be an integer in \[1, "):
        run_sweep(Sweep(base={"x": 1.0}), square, tmp_path / "d", workers=0, progress=False)


def square(params):
    return {"y": params["x"] ** 2}


def reserved_key(params):
    return {"status": 1}


def test_summarize_and_plot(tmp_path, log):
    result = run_sweep(SWEEP, Toy(str(log)), tmp_path / "out", workers=1, progress=False)
    summary = summarize(result.table, "y", "x")
    assert [s["x"] for s in summary] == [1.0, 2.0, 3.0, 4.0] and all(s["n"] == 2 for s in summary)
    for s in summary:
        values = np.array([10 * s["x"], 10 * s["x"] + 1])
        assert s["mean"] == pytest.approx(values.mean())
        assert s["se"] == pytest.approx(values.std(ddof=1) / math.sqrt(2))
    grouped = summarize(result.rows, "y", "x", group="seed", where={"x": "2.0"})
    assert [(s["group"], s["x"], s["n"], s["mean"]) for s in grouped] == [(0, 2.0, 1, 20.0), (1, 2.0, 1, 21.0)]
    assert math.isnan(grouped[0]["se"])
    png = save_sweep_plot(tmp_path / "y.png", result.table, "y", "x", group="even")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(ValueError, match="no column 'z'"):
        summarize(result.table, "z", "x")
    with pytest.raises(ValueError, match="'x' varies among the runs"):  # x is swept: averaging over it is an error
        summarize(result.table, "y", "even")


def test_damaged_sweep_records_are_run_again_and_damaged_tables_are_one_line(tmp_path, capsys):
    sweep = Sweep(base={"x": 1.0}, axes={"x": [1.0, 2.0]})
    result = run_sweep(sweep, square, tmp_path / "s", workers=1, progress=False)
    record = next((tmp_path / "s" / "runs").iterdir())
    data = json.loads(record.read_text())
    data["row"] = ["not", "a", "row"]
    record.write_text(json.dumps(data))
    again = run_sweep(sweep, square, tmp_path / "s", workers=1, progress=False)
    assert again.ran == 1 and again.rows == [dict(r, wall_s=a["wall_s"]) for r, a in zip(result.rows, again.rows)]
    table = tmp_path / "s" / "table.csv"
    lines = table.read_text().splitlines()
    table.write_text("\n".join(lines[:-1] + [lines[-1][: len(lines[-1]) // 3]]) + "\n")  # truncated mid-row
    assert qdots_main(["sweep-plot", str(table), "--metric", "y", "--x", "x"]) == 2
    one_line_error(capsys)
    table.write_text("\n".join(lines) + "\n")
    assert qdots_main(["sweep-plot", str(table), "--metric", "status", "--x", "x"]) == 2
    assert "holds no numbers" in one_line_error(capsys)


def test_a_table_cut_at_a_row_boundary_is_refused_by_sweep_plot(tmp_path, capsys, log):
    result = run_sweep(SWEEP, Toy(str(log)), tmp_path / "out", workers=1, progress=False)
    table = result.table
    lines = table.read_text().splitlines()
    assert len(lines) == 9
    argv = ["sweep-plot", str(table), "--metric", "y", "--x", "x"]
    assert qdots_main(argv) == 0  # whole: plotted
    capsys.readouterr()
    table.write_text("\n".join(lines[:6]) + "\n")  # two thirds of it: it ends on a row boundary
    assert qdots_main(argv) == 2
    err = one_line_error(capsys)
    assert "the table has 5 rows for the 8 runs that sweep.json beside it lists (3 missing" in err
    if result.parquet is not None:  # the Parquet table is checked too
        import pyarrow.parquet as pq

        pq.write_table(pq.read_table(result.parquet).slice(0, 4), result.parquet)
        assert qdots_main(["sweep-plot", str(result.parquet), "--metric", "y", "--x", "x"]) == 2
        assert "the table has 4 rows for the 8 runs" in one_line_error(capsys)
    assert summarize([dict(r) for r in result.rows][:5], "y", "x")  # rows given directly: no sweep to check


def test_sweep_plot_writes_only_a_png(tmp_path, capsys, log):
    result = run_sweep(SWEEP, Toy(str(log)), tmp_path / "out", workers=1, progress=False)
    out = tmp_path / "x.txt"
    assert qdots_main(["sweep-plot", str(result.table), "--metric", "y", "--x", "x", "--out", str(out)]) == 2
    assert "--out must name a .png file" in one_line_error(capsys) and not out.exists()
    out = tmp_path / "plot.PNG"
    assert qdots_main(["sweep-plot", str(result.table), "--metric", "y", "--x", "x", "--out", str(out)]) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
