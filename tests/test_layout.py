"""The packages' layout: planarize and labrig stand without qdots and without pymunk."""

import subprocess
import sys
import textwrap

import pytest

BLOCKED_RUN = textwrap.dedent("""
    import importlib.abc, sys

    class Blocked(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] in {"qdots", "pymunk"}:
                raise ModuleNotFoundError(f"{name} is blocked in this test", name=name)
            return None

    sys.meta_path.insert(0, Blocked())
    import labrig, labrig.sweeps
    import planarize, planarize.io, planarize.cli, planarize.render
    from planarize import Fast, anodize, surfaces
    run = anodize(surfaces.hill(points=5, refine=2), 0.5, engine=Fast())
    assert run.complete and run.thickness >= 0.5, run.thickness
    loaded = sorted(m for m in sys.modules if m.split(".")[0] in {"qdots", "pymunk"})
    assert not loaded, loaded
    print("ok")
""")


@pytest.mark.parametrize("code", [BLOCKED_RUN], ids=["planarize-without-qdots-and-pymunk"])
def test_planarize_imports_and_runs_with_qdots_and_pymunk_unavailable(code):
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip().endswith("ok")
