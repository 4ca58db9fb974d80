"""Every notebook runs top to bottom in quick mode (they carry their own asserts)."""

from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

NOTEBOOKS = sorted((Path(__file__).parent.parent / "notebooks").glob("*.ipynb"))
MICROGRAPH = Path(__file__).resolve().parent.parent.parent / "shared" / "data" / "micrographs" / "nanoparticle_film_tem.png"


#: The notebooks whose quick run takes half a minute or more (a library of films and a posterior trained, a sweep of
#: 24 films, the Ta film's anodization): marked slow, so that the default suite stays within its 10 minutes of CPU.
HEAVY = ("02_analysis_lqe.ipynb", "04_planarize_ta.ipynb", "06_micrograph.ipynb")


@pytest.mark.parametrize("path", [pytest.param(p, marks=pytest.mark.slow) if p.name in HEAVY else p for p in NOTEBOOKS],
                         ids=[p.name for p in NOTEBOOKS])
def test_notebook_runs(path, tmp_path, monkeypatch):
    monkeypatch.setenv("QDOTS_QUICK", "0.1")  # the kernel inherits it: scaled-down runs
    if MICROGRAPH.exists():  # notebook 06 measures the shared test micrograph (else a synthetic film)
        monkeypatch.setenv("QDOTS_MICROGRAPH", str(MICROGRAPH))
    notebook = nbformat.read(path, as_version=4)
    NotebookClient(notebook, timeout=600, kernel_name="python3",
                   resources={"metadata": {"path": str(tmp_path)}}).execute()
