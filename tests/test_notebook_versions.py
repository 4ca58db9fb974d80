"""The committed notebooks show what this version of the code does (fast: nothing is executed).

Each was executed by ``python -m notebooks.execute`` with the current ``labrig.__version__`` (a
release bumps the version, so this fails until the notebooks are re-executed), in one pass, with
the first cell saying at what scale and how long it ran, and with no machine path stored.
"""

import copy
import json
import subprocess
import sys

import nbformat
import pytest

import labrig
from notebooks.execute import (
    KEY,
    LINE_START,
    NOTEBOOKS,
    WIDGET_STATE,
    format_duration,
    problems,
    set_status_line,
    status_line,
)

PATHS = sorted(NOTEBOOKS.glob("*.ipynb"))
RECORD = {"version": labrig.__version__, "executed": "2026-11-27T04:00:00+00:00", "wall_s": 312.4, "scale": "full",
          "cores": 2}


def _read(path):
    return json.loads(path.read_text(encoding="utf-8"))


@pytest.mark.parametrize("path", PATHS, ids=[p.name for p in PATHS])
def test_committed_notebook_was_executed_by_this_version(path):
    assert problems(_read(path), labrig.__version__) == []


def test_interactive_notebook_shows_its_widgets_without_a_kernel():
    notebook = _read(NOTEBOOKS / "05_interactive.ipynb")
    state = notebook["metadata"]["widgets"][WIDGET_STATE]["state"]
    canvases = [m for m in state.values() if m["model_name"] == "MPLCanvasModel"]
    assert len(canvases) == 3  # the board, the hill's explorer, the AFM scan's explorer
    assert all(m["state"]["_data_url"].startswith("data:image/png;base64,") for m in canvases)
    # and a picture of each, for pages that draw no widgets (a repository page, the documentation site)
    pictures = [o for c in notebook["cells"] for o in c.get("outputs", []) if "image/png" in o.get("data", {})]
    assert len(pictures) >= 3


def _fake(version=RECORD["version"], **changes):
    """A small executed notebook as the tool writes it."""
    notebook = nbformat.v4.new_notebook()
    notebook.cells = [nbformat.v4.new_markdown_cell("# A title\n\nWhat it shows."),
                      nbformat.v4.new_code_cell("x = 1"), nbformat.v4.new_code_cell("print(x)")]
    notebook.cells[1].execution_count, notebook.cells[2].execution_count = 1, 2
    notebook.cells[2].outputs = [nbformat.v4.new_output("stream", name="stdout", text="1\n")]
    notebook.metadata[KEY] = {**RECORD, "version": version, **changes}
    set_status_line(notebook, status_line(notebook.metadata[KEY]))
    return json.loads(nbformat.writes(notebook))


def test_problems_accepts_a_notebook_as_the_tool_writes_it():
    notebook = _fake()
    assert problems(notebook, RECORD["version"]) == []
    assert "".join(notebook["cells"][0]["source"]).endswith(
        f"\n\n*Executed with nanodisorder {RECORD['version']} at full size in 5 min on a 2-core machine, 2026-11-27.*")


def test_problems_fails_a_notebook_executed_by_another_version():
    found = problems(_fake(version="0.1.9"), "0.2.0")
    assert len(found) == 1 and "executed by nanodisorder 0.1.9, not 0.2.0" in found[0]
    assert problems(_fake(version="0.2.0"), "0.2.0") == []
    unrecorded = _fake()
    del unrecorded["metadata"][KEY]
    assert "not executed by notebooks/execute.py" in problems(unrecorded, RECORD["version"])[0]


def test_problems_fails_stale_or_missing_first_line():
    notebook = _fake()
    notebook["metadata"][KEY]["wall_s"] = 4000.0  # the line still says 5 min
    assert any("the first cell should say" in p for p in problems(notebook, RECORD["version"]))
    notebook = _fake(scale="0.1")
    assert "in quick mode (QDOTS_QUICK=0.1)" in "".join(notebook["cells"][0]["source"])
    notebook["cells"][0]["source"] = "# A title"
    assert any("the first cell should say" in p for p in problems(notebook, RECORD["version"]))


def test_problems_fails_cells_not_run_in_one_pass_and_errors():
    notebook = _fake()
    notebook["cells"][2]["execution_count"] = 5
    assert any("one pass" in p for p in problems(notebook, RECORD["version"]))
    notebook = _fake()
    notebook["cells"][2]["outputs"].append({"output_type": "error", "ename": "ValueError", "evalue": "bad",
                                            "traceback": []})
    assert any("ValueError: bad" in p for p in problems(notebook, RECORD["version"]))


#: Paths as other machines have them (a checkout, a home, a temporary folder, a Windows drive, a package).
MACHINE_PATH_EXAMPLES = ("/srv/lab/checkout/", "/Users/ana/", "/var/folders/x1/", "C:\\Users\\ana\\",
                         "lib/python3.11/site-packages/")


@pytest.mark.parametrize("where", ["stream", "html", "widget"])
@pytest.mark.parametrize("prefix", MACHINE_PATH_EXAMPLES)
def test_problems_fails_machine_paths(where, prefix):
    notebook = _fake()
    outputs = notebook["cells"][2]["outputs"]
    path = f"{prefix}somewhere/board.npz"
    if where == "stream":
        outputs[0]["text"] = f"saved {path}\n"
    elif where == "html":
        outputs.append({"output_type": "display_data", "metadata": {},
                        "data": {"text/html": f"<b>{path}</b>", "text/plain": "x"}})
    else:
        notebook["metadata"]["widgets"] = {WIDGET_STATE: {"version_major": 2, "version_minor": 0, "state": {
            "m1": {"model_name": "TextModel", "model_module": "@jupyter-widgets/controls",
                   "model_module_version": "2.0.0", "state": {"value": path}}}}}
    found = problems(notebook, RECORD["version"])
    assert len(found) == 1 and "machine path" in found[0]


def test_pictures_are_not_searched_for_paths():
    # base64 pictures contain path-like runs by chance; a data URL or image output is not text
    notebook = _fake()
    notebook["cells"][2]["outputs"].append({"output_type": "display_data", "metadata": {},
                                            "data": {"image/png": f"iVBOR{MACHINE_PATH_EXAMPLES[0]}AAAA", "text/plain": "<Figure>"}})
    assert problems(notebook, RECORD["version"]) == []


def test_widget_outputs_need_their_state_and_canvases_their_picture():
    notebook = _fake()
    notebook["cells"][2]["outputs"].append({"output_type": "display_data", "metadata": {}, "data": {
        "application/vnd.jupyter.widget-view+json": {"model_id": "c1", "version_major": 2, "version_minor": 0},
        "text/plain": "Canvas"}})
    assert any("whose state is not stored" in p for p in problems(notebook, RECORD["version"]))
    canvas = {"model_name": "MPLCanvasModel", "model_module": "jupyter-matplotlib", "model_module_version": "^0.10",
              "state": {"_data_url": None}}
    notebook["metadata"]["widgets"] = {WIDGET_STATE: {"version_major": 2, "version_minor": 0, "state": {"c1": canvas}}}
    assert any("shows blank" in p for p in problems(notebook, RECORD["version"]))
    canvas["state"]["_data_url"] = "data:image/png;base64,iVBOR"
    assert problems(notebook, RECORD["version"]) == []


def test_status_line_is_replaced_not_added_again():
    notebook = nbformat.reads(json.dumps(_fake()), as_version=4)
    first = notebook.cells[0].source
    set_status_line(notebook, status_line({**RECORD, "wall_s": 30.0, "scale": "0.25"}))
    lines = notebook.cells[0].source.split("\n")
    assert [line for line in lines if line.startswith(LINE_START)] == [
        f"{LINE_START}{RECORD['version']} in quick mode (QDOTS_QUICK=0.25) in 30 s on a 2-core machine, 2026-11-27.*"]
    assert len(lines) == len(first.split("\n"))
    assert [format_duration(s) for s in (7, 89, 300, 5399, 9000)] == ["7 s", "89 s", "5 min", "90 min", "2.5 h"]


def test_check_command_reports_this_checkout(tmp_path):
    # the command line's --check is the same check; it runs from the repository root as a module
    broken = tmp_path / "broken.ipynb"
    notebook = copy.deepcopy(_fake(version="0.0.1"))
    broken.write_text(json.dumps(notebook), encoding="utf-8")
    result = subprocess.run([sys.executable, "-m", "notebooks.execute", "--check", str(broken)],
                            cwd=NOTEBOOKS.parent, capture_output=True, text=True, timeout=120)
    assert result.returncode == 1 and "executed by nanodisorder 0.0.1" in result.stdout
