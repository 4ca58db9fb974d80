"""The packages' layout: planarize and labrig stand without qdots and without pymunk."""

import subprocess
import sys
import textwrap

import pytest

from labrig.tomlfile import tomllib

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


NO_SIDE_EFFECTS = textwrap.dedent("""
    import importlib, sys

    before = list(sys.meta_path)
    import qdots, planarize
    assert sys.meta_path == before, [type(finder).__name__ for finder in sys.meta_path]
    # the module names and attribute names of 0.1 are gone, not served by a hook
    for old in ("qdots.structure", "qdots.neighbors", "qdots.scenefile", "planarize.scenes", "planarize.fast",
                "planarize.scenefile"):
        try:
            importlib.import_module(old)
        except ModuleNotFoundError:
            pass
        else:
            raise AssertionError(f"{old} still imports")
    for module, old in ((qdots, "CenterGravity"), (qdots.forces, "CenterGravity"), (planarize, "scenes")):
        assert not hasattr(module, old), (module.__name__, old)
    print("ok")
""")


def test_importing_the_packages_installs_no_import_hooks():
    done = subprocess.run([sys.executable, "-W", "error::DeprecationWarning", "-c", NO_SIDE_EFFECTS],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip().endswith("ok")


def test_a_warning_fails_the_test_suite(tmp_path):
    """The pytest configuration makes every warning an error (pyproject.toml), so the suite stays warning-free."""
    from pathlib import Path

    import tomllib

    root = Path(__file__).resolve().parent.parent
    config = tomllib.loads((root / "pyproject.toml").read_text())["tool"]["pytest"]["ini_options"]
    assert config["filterwarnings"][0] == "error"
    (tmp_path / "test_warns.py").write_text("import warnings\n\n\ndef test_it():\n"
                                            "    warnings.warn('leaked', RuntimeWarning)\n")
    done = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-c",
                           str(root / "pyproject.toml"), "--rootdir", str(tmp_path), str(tmp_path / "test_warns.py")],
                          capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert done.returncode == 1 and "RuntimeWarning: leaked" in done.stdout, done.stdout[-2000:]


def test_a_release_states_its_version_licence_and_types():
    """The changelog's newest entry is this version's and names the physics it changed; the licence file is the
    one pyproject declares; each package says its type hints are part of it (PEP 561)."""
    from pathlib import Path

    import labrig

    root = Path(__file__).resolve().parent.parent
    changelog = (root / "CHANGELOG.md").read_text(encoding="utf-8")
    newest = changelog.split("\n## ")[1]
    assert newest.startswith(f"{labrig.__version__} ("), newest[:40]
    for change in ("event engine", "20 ms frame", "impacts at contact", "continuum engine"):
        assert change in newest.lower(), change
    pyproject = tomllib.loads((root / "pyproject.toml").read_text(encoding="utf-8"))
    assert pyproject["project"]["license"] == {"text": "MIT"}
    assert (root / "LICENSE").read_text(encoding="utf-8").startswith("MIT License\n")
    for package in ("labrig", "qdots", "planarize"):
        assert (root / package / "py.typed").is_file(), package
    assert pyproject["tool"]["setuptools"]["package-data"]["*"] == ["py.typed"]
