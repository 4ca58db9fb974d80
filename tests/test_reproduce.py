"""``python -m reproduce``: the report it writes, ``--only`` merging, resuming the film sweep, bad input.

The whole quick pipeline (every item, 24 scaled-down film runs on each engine) is marked slow; the CLI
contract and one planarize item run by default.
"""

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from reproduce.__main__ import ITEMS
from reproduce.item import VERDICTS, Item, Quote, apart, mean_se

ROOT = Path(__file__).resolve().parent.parent
THESIS = ROOT.parent / "shared" / "seed" / "thesis.txt"


def reproduce(*args):
    return subprocess.run([sys.executable, "-m", "reproduce", *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=900)


def plain(text: str) -> str:
    """Text without the scan's markdown and TeX markup, whitespace collapsed."""
    return " ".join(re.sub(r"[*$]", "", text).split())


def check_report(out: Path, keys) -> dict:
    store = json.loads((out / "reproduction.json").read_text())
    report = (out / "reproduction.md").read_text()
    assert sorted(store["items"]) == sorted(keys)
    for key, item in store["items"].items():
        assert item["verdict"] in VERDICTS and item["why"].strip(), key
        assert f'<a id="{key}"></a>' in report and f"**Verdict: {item['verdict']}.**" in report
        for name in [part.split(")")[0] for part in item["markdown"].split("](figures/")[1:]]:
            assert (out / "figures" / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        if THESIS.is_file():  # every quote is the thesis's own words (markup aside), on the line given
            lines = THESIS.read_text(encoding="utf-8").splitlines()
            for quote in item["thesis"]:
                for part in quote["text"].split("..."):
                    assert plain(part) in plain(lines[quote["line"] - 1]), (key, quote["line"], part)
    return store


@pytest.mark.slow
def test_one_item_then_another_keeps_the_first(tmp_path):
    run = reproduce("--quick", "--only", "fig3-8", "--out", str(tmp_path))
    assert run.returncode == 0, run.stderr[-3000:]
    check_report(tmp_path, ["fig3-8"])
    run = reproduce("--quick", "--only", "fig3-13", "--out", str(tmp_path))
    assert run.returncode == 0, run.stderr[-3000:]
    store = check_report(tmp_path, ["fig3-8", "fig3-13"])
    assert store["items"]["fig3-13"]["mode"] == "quick"


@pytest.mark.parametrize("args, needle", [(["--only", "fig9-9"], "--only: unknown item 'fig9-9'"),
                                          (["--seeds", "0"], "--seeds must be an integer in [1, 100]"),
                                          (["--workers", "0"], "--workers must be an integer in [1, 64]")])
def test_bad_arguments_fail_in_one_line_and_write_nothing(tmp_path, args, needle):
    (tmp_path / "reproduction.md").write_text("before")
    run = reproduce("--quick", *args, "--out", str(tmp_path))
    assert run.returncode == 2 and run.stderr.strip().count("\n") == 0 and needle in run.stderr, run.stderr
    assert (tmp_path / "reproduction.md").read_text() == "before"


def test_unreadable_previous_data_is_not_overwritten(tmp_path):
    (tmp_path / "reproduction.json").write_text("{not json")
    run = reproduce("--quick", "--only", "fig3-8", "--out", str(tmp_path))
    assert run.returncode == 2 and "move it away" in run.stderr
    assert (tmp_path / "reproduction.json").read_text() == "{not json"


def test_statistics_and_verdict_names():
    assert mean_se([1.0, 2.0, 3.0]) == pytest.approx((2.0, 1.0 / 3 ** 0.5))
    assert mean_se([4.0, float("nan")])[0] == 4.0
    assert apart((1.0, 0.1), (1.5, 0.1)) and not apart((1.0, 0.1), (1.2, 0.1))
    assert not apart((1.0, float("nan")), (5.0, 0.1))  # one seed: no claim either way
    with pytest.raises(ValueError, match="verdict must be one of"):
        Item("x", "x", [Quote(1, "x")], verdict="close enough")


@pytest.mark.slow
@pytest.mark.release
def test_whole_quick_set_writes_every_item_and_resumes_the_films(tmp_path):
    runs = tmp_path / "runs"
    run = reproduce("--quick", "--out", str(tmp_path), "--runs", str(runs))
    assert run.returncode == 0, run.stderr[-3000:]
    store = check_report(tmp_path, ITEMS)
    assert store["films"]["runs"] == 2 * 24  # both engines

    def stamps():
        return {p: p.stat().st_mtime_ns for engine in ("event", "chipmunk")
                for p in (runs / f"films-quick-{engine}" / "runs").iterdir()}

    before = stamps()
    assert len(before) == 48
    run = reproduce("--quick", "--only", "fig2-4", "--out", str(tmp_path), "--runs", str(runs))
    assert run.returncode == 0, run.stderr[-3000:]
    assert stamps() == before  # none re-run
    assert json.loads((tmp_path / "reproduction.json").read_text())["items"].keys() == store["items"].keys()
