"""Execute the notebooks in place with the current code, and check what a committed notebook says about its run.

A notebook's stored outputs are what the code did when it ran. This tool runs notebooks top to bottom
(nbclient, the kernel in the notebook's folder, widget state kept), and records in the notebook's
metadata which version of nanodisorder ran it, when, at what scale and for how long::

    metadata["nanodisorder"] = {"version": "0.2.0", "executed": "2026-11-27T04:10:00+00:00",
                                "wall_s": 312.4, "scale": "full", "cores": 2}

and says the same on a line of the first (markdown) cell, which it replaces on every run::

    *Executed with nanodisorder 0.2.0 at full size in 5 min on a 2-core machine, 2026-11-27.*

The test suite (``tests/test_notebook_versions.py``) checks every committed notebook with `problems`:
executed by this version (``labrig.__version__``; a release bumps it, so a release re-executes them),
every code cell run in one pass, that line beside the metadata, no machine path in what is stored.

Usage, from the repository root::

    python -m notebooks.execute                 # all notebooks, at full size, one at a time
    python -m notebooks.execute 05 06           # those whose names start so
    python -m notebooks.execute --quick 0.1 00  # scaled down (QDOTS_QUICK): a quick look, recorded as such

Notebook 06 measures the shared TEM micrograph beside the checkout
(``../shared/data/micrographs/nanoparticle_film_tem.png``, as the tests do) when it is there. The
sweeps the notebooks keep under ``notebooks/sweeps/`` (a cache, not in git) are removed first, so
that every run is made by the current code (``--keep-sweeps`` reuses them).
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import re
import shutil
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
#: The notebooks' folder.
NOTEBOOKS = ROOT / "notebooks"
#: The real micrograph notebook 06 measures, beside the checkout (not part of it).
MICROGRAPH = ROOT.parent / "shared" / "data" / "micrographs" / "nanoparticle_film_tem.png"
#: Metadata key of the record of a run.
KEY = "nanodisorder"
#: How the first cell's line about the run starts (the tool finds and replaces it by this).
LINE_START = "*Executed with nanodisorder "
#: Default longest time a cell may run, s.
CELL_TIMEOUT = 4 * 3600
#: What says a stored output or widget state holds a path on the machine that ran it: an absolute path of two or
#: more parts (``/a/b``: not a URL's, a fraction's or a unit's slash), a Windows drive path, an installed package.
MACHINE_PATH = re.compile(r"(?<![\w.:/~-])/(?:[\w.-]+/)+[\w.-]*|\b[A-Za-z]:\\|site-packages")
#: Output types whose data is text (pictures are base64, where such strings occur by chance).
TEXT_TYPES = ("text/", "application/json", "application/javascript", "application/vnd.jupyter.widget-view+json")
WIDGET_STATE = "application/vnd.jupyter.widget-state+json"
WIDGET_VIEW = "application/vnd.jupyter.widget-view+json"


def current_version() -> str:
    """The version of nanodisorder this checkout is (``labrig.__version__``)."""
    import labrig

    return labrig.__version__


def format_duration(seconds: float) -> str:
    """A run's wall time as the first cell says it: ``"48 s"``, ``"7 min"``, ``"2.5 h"``."""
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 90 * 60:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"


def status_line(record: dict) -> str:
    """The first cell's line for the run ``record`` (a notebook's ``metadata["nanodisorder"]``)."""
    scale = record["scale"]
    at = "at full size" if scale == "full" else f"in quick mode (QDOTS_QUICK={scale})"
    return (f"{LINE_START}{record['version']} {at} in {format_duration(record['wall_s'])} "
            f"on a {record['cores']}-core machine, {record['executed'][:10]}.*")


def set_status_line(notebook, line: str) -> None:
    """Put ``line`` in the first cell (markdown): replace the line that starts with `LINE_START`, or add it.

    A notebook whose first cell is not markdown gets a markdown cell holding only the line.
    """
    import nbformat

    cells = notebook.cells
    if not cells or cells[0].cell_type != "markdown":
        cells.insert(0, nbformat.v4.new_markdown_cell(line))
        return
    lines = cells[0].source.split("\n")
    found = [i for i, text in enumerate(lines) if text.startswith(LINE_START)]
    if found:
        lines[found[0]] = line
        for i in reversed(found[1:]):
            del lines[i]
    else:
        while lines and not lines[-1].strip():
            lines.pop()
        lines += ["", line]
    cells[0].source = "\n".join(lines)


def _texts(value):
    """Every string inside a JSON value, except data URLs (base64 pictures)."""
    if isinstance(value, str):
        if not value.startswith("data:"):
            yield value
    elif isinstance(value, dict):
        for item in value.values():
            yield from _texts(item)
    elif isinstance(value, list):
        for item in value:
            yield from _texts(item)


def _output_texts(output: dict):
    """The text of one stored output: streams, tracebacks, and the textual types of its data."""
    if output.get("output_type") == "stream":
        yield "".join(output.get("text", ""))
    if output.get("output_type") == "error":
        yield from output.get("traceback", [])
    for kind, data in output.get("data", {}).items():
        if kind.startswith(TEXT_TYPES):
            yield from _texts(data)


def machine_paths(notebook: dict) -> list[str]:
    """Where ``notebook`` stores a path of the machine it ran on (outputs and widget state), as messages."""
    found = []

    def look(where: str, texts) -> None:
        for text in texts:
            text = "".join(text) if isinstance(text, list) else text
            hit = MACHINE_PATH.search(text)
            if hit:
                start = max(0, hit.start() - 30)
                found.append(f"{where} holds a machine path ({hit.group()!r}): ...{text[start:start + 90]!r}...")
                return

    for index, cell in enumerate(notebook.get("cells", [])):
        for output in cell.get("outputs", []):
            look(f"cell {index}'s output", _output_texts(output))
    state = notebook.get("metadata", {}).get("widgets", {}).get(WIDGET_STATE, {}).get("state", {})
    look("the widget state", _texts(state))
    return found


def problems(notebook: dict, version: str) -> list[str]:
    """What is wrong with a committed notebook's record of its run; ``[]`` when nothing is.

    Parameters
    ----------
    notebook : dict
        The notebook as read by ``nbformat.read`` (or plain ``json.load``).
    version : str
        The version that must have executed it (`current_version`).

    Returns
    -------
    list of str
        One message per problem: no record or one from another version, a code cell not run (or
        not run in one pass from the top), an error output, the first cell's line missing or not
        saying what the record says, a widget output without its stored state, an ipympl canvas
        without its picture, a machine path in an output or the widget state.
    """
    found = []
    record = notebook.get("metadata", {}).get(KEY)
    if not isinstance(record, dict):
        return [f"no metadata[{KEY!r}]: not executed by notebooks/execute.py"]
    if record.get("version") != version:
        found.append(f"executed by nanodisorder {record.get('version')}, not {version}: re-execute it "
                     "(python -m notebooks.execute)")
    keys = ("version", "executed", "wall_s", "scale", "cores")
    missing = [k for k in keys if k not in record]
    if missing:
        return found + [f"metadata[{KEY!r}] lacks {missing}"]
    cells = notebook.get("cells", [])
    code = [c for c in cells if c.get("cell_type") == "code" and "".join(c.get("source", "")).strip()]
    counts = [c.get("execution_count") for c in code]
    if counts != list(range(1, len(code) + 1)):
        found.append(f"the code cells were not all run in one pass from the top (execution counts {counts})")
    if not any(c.get("outputs") for c in code):
        found.append("no code cell has a stored output")
    for index, cell in enumerate(cells):
        for output in cell.get("outputs", []):
            if output.get("output_type") == "error":
                found.append(f"cell {index} stored an error: {output.get('ename')}: {output.get('evalue')}")
    first = "".join(cells[0].get("source", "")) if cells and cells[0].get("cell_type") == "markdown" else ""
    lines = [line for line in first.split("\n") if line.startswith(LINE_START)]
    if lines != [status_line(record)]:
        found.append(f"the first cell should say {status_line(record)!r}, says {lines}")
    found += _widget_problems(notebook)
    found += machine_paths(notebook)
    return found


def _widget_problems(notebook: dict) -> list[str]:
    """Widget outputs whose model is not stored, and stored ipympl canvases without a picture."""
    state = notebook.get("metadata", {}).get("widgets", {}).get(WIDGET_STATE, {}).get("state", {})
    found = []
    for index, cell in enumerate(notebook.get("cells", [])):
        for output in cell.get("outputs", []):
            view = output.get("data", {}).get(WIDGET_VIEW)
            if view and view.get("model_id") not in state:
                found.append(f"cell {index} shows widget {view.get('model_id')} whose state is not stored")
    for model_id, model in state.items():
        if model.get("model_name") == "MPLCanvasModel":
            url = model.get("state", {}).get("_data_url") or ""
            if not url.startswith("data:image/png;base64,"):
                found.append(f"ipympl canvas {model_id} has no stored picture: it shows blank without a kernel")
    return found


def _kernel_env(quick: str | None, micrograph: Path | None) -> dict:
    env = dict(os.environ)
    env.pop("QDOTS_QUICK", None)
    if quick is not None:
        env["QDOTS_QUICK"] = quick
    if micrograph is not None and micrograph.exists():
        env["QDOTS_MICROGRAPH"] = str(micrograph)
    return env


def _clear_sweeps(notebook, folder: Path) -> list[str]:
    """Remove the sweep folders (``sweeps/NAME`` under ``folder``) that ``notebook``'s code names."""
    names = set()
    for cell in notebook.cells:
        if cell.cell_type == "code":
            names.update(re.findall(r"""["']sweeps/([\w.-]+)["']""", cell.source))
    removed = []
    for name in sorted(names):
        target = folder / "sweeps" / name
        if target.is_dir():
            shutil.rmtree(target)
            removed.append(f"sweeps/{name}")
    return removed


def write_atomic(notebook, path: Path) -> None:
    """Write ``notebook`` to ``path`` through a temporary file in the same folder (never half written)."""
    import nbformat

    handle, temporary = tempfile.mkstemp(prefix=f".{path.stem}-", suffix=".ipynb", dir=path.parent)
    try:
        with os.fdopen(handle, "w", encoding="utf-8") as stream:
            nbformat.write(notebook, stream)
        os.chmod(temporary, path.stat().st_mode & 0o777 if path.exists() else 0o644)
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def execute(path: Path, *, quick: str | None = None, timeout: int = CELL_TIMEOUT,
            micrograph: Path | None = MICROGRAPH, keep_sweeps: bool = False) -> dict:
    """Execute the notebook at ``path`` in place and record the run; returns the record.

    Parameters
    ----------
    path : Path
        The notebook; its kernel runs in the notebook's folder.
    quick : str, optional
        ``QDOTS_QUICK`` for the kernel (a scaled-down run, recorded as such); None: full size
        (``QDOTS_QUICK`` unset even if this process has it).
    timeout : int
        Longest time one cell may run, s.
    micrograph : Path, optional
        ``QDOTS_MICROGRAPH`` for the kernel, when the file exists.
    keep_sweeps : bool
        Reuse the runs of the sweeps the notebook keeps (default: remove them first).

    Raises
    ------
    nbclient.exceptions.CellExecutionError
        When a cell fails; the notebook file is then left as it was.
    """
    import nbformat
    from nbclient import NotebookClient

    path = Path(path).resolve()
    notebook = nbformat.read(path, as_version=4)
    notebook.metadata.pop("widgets", None)  # a run without widgets must not keep an older run's state
    notebook.metadata.pop(KEY, None)
    if not keep_sweeps:
        for name in _clear_sweeps(notebook, path.parent):
            print(f"  removed {name} (runs again with this code)", flush=True)
    client = NotebookClient(notebook, timeout=timeout, kernel_name="python3", store_widget_state=True,
                            resources={"metadata": {"path": str(path.parent)}})
    started = time.perf_counter()
    client.execute(env=_kernel_env(quick, micrograph))
    record = {"version": current_version(),
              "executed": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
              "wall_s": round(time.perf_counter() - started, 1),
              "scale": "full" if quick is None else quick,
              "cores": os.cpu_count() or 1}
    notebook.metadata[KEY] = record
    set_status_line(notebook, status_line(record))
    nbformat.validate(notebook)
    write_atomic(notebook, path)
    return record


def select(names: list[str], folder: Path = NOTEBOOKS) -> list[Path]:
    """The notebooks of ``folder`` whose file names start with one of ``names`` (all of them if none)."""
    every = sorted(folder.glob("*.ipynb"))
    if not names:
        return every
    chosen = []
    for name in names:
        given = Path(name)
        if given.suffix == ".ipynb" and given.exists():
            chosen.append(given.resolve())
            continue
        matches = [p for p in every if p.name.startswith(name)]
        if not matches:
            raise SystemExit(f"no notebook in {folder.name}/ starts with {name!r}")
        chosen += matches
    return list(dict.fromkeys(chosen))


def main(argv: list[str] | None = None) -> int:
    """Command line: execute the chosen notebooks one at a time; 1 if one failed."""
    parser = argparse.ArgumentParser(prog="python -m notebooks.execute", description=__doc__.split("\n")[0])
    parser.add_argument("names", nargs="*", help="notebooks (file names or their starts, e.g. 05); default: all")
    parser.add_argument("--quick", metavar="FACTOR", help="run scaled down (QDOTS_QUICK=FACTOR); default: full size")
    parser.add_argument("--timeout", type=int, default=CELL_TIMEOUT, help="longest time a cell may run, s "
                        f"(default {CELL_TIMEOUT})")
    parser.add_argument("--keep-sweeps", action="store_true", help="reuse the runs the notebooks' sweeps kept")
    parser.add_argument("--check", action="store_true", help="only check the notebooks (no execution)")
    args = parser.parse_args(argv)
    if args.quick is not None:
        try:
            if not 0 < float(args.quick) <= 1:
                raise ValueError
        except ValueError:
            parser.error(f"--quick must be a number in (0, 1], got {args.quick!r}")
    paths = select(args.names)
    failed = 0
    if args.check:
        version = current_version()
        for path in paths:
            found = problems(json.loads(path.read_text(encoding="utf-8")), version)
            print(f"{path.name}: " + ("ok" if not found else "\n  ".join([""] + found)))
            failed += bool(found)
        return int(bool(failed))
    for path in paths:
        scale = "at full size" if args.quick is None else f"QDOTS_QUICK={args.quick}"
        print(f"{path.name}: executing {scale} ...", flush=True)
        try:
            record = execute(path, quick=args.quick, timeout=args.timeout, keep_sweeps=args.keep_sweeps)
        except Exception as exc:  # a failing cell, a timeout, a dead kernel: the others still run
            failed += 1
            print(f"{path.name}: FAILED, left as it was:\n{str(exc)[-3000:]}", file=sys.stderr, flush=True)
            continue
        print(f"{path.name}: done in {format_duration(record['wall_s'])} ({record['wall_s']} s)", flush=True)
    return int(bool(failed))


if __name__ == "__main__":
    sys.exit(main())
