"""Every notebook runs top to bottom in quick mode (they carry their own asserts)."""

from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

NOTEBOOKS = sorted((Path(__file__).parent.parent / "notebooks").glob("*.ipynb"))
MICROGRAPH = Path(__file__).resolve().parent.parent.parent / "shared" / "data" / "micrographs" / "nanoparticle_film_tem.png"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.name for p in NOTEBOOKS])
def test_notebook_runs(path, tmp_path, monkeypatch):
    monkeypatch.setenv("QDOTS_QUICK", "0.1")  # the kernel inherits it: scaled-down runs
    if MICROGRAPH.exists():  # notebook 06 measures the shared test micrograph (else a synthetic film)
        monkeypatch.setenv("QDOTS_MICROGRAPH", str(MICROGRAPH))
    notebook = nbformat.read(path, as_version=4)
    NotebookClient(notebook, timeout=600, kernel_name="python3",
                   resources={"metadata": {"path": str(tmp_path)}}).execute()
