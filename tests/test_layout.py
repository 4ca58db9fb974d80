"""The packages' layout: planarize and labrig stand without qdots and without pymunk; imports only point down, take
no private name and make no cycle (ARCHITECTURE.md)."""

import ast
import re
import subprocess
import sys
import textwrap
from pathlib import Path

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


# -- the import graph, read from the source (ARCHITECTURE.md's rules) ---------------------------------------------

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("labrig", "qdots", "planarize")
#: What each package may import of the others: an arrow only points down.
MAY_IMPORT = {"labrig": set(), "qdots": {"labrig"}, "planarize": {"labrig"}}


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {module_name(p): p for package in PACKAGES for p in sorted((ROOT / package).rglob("*.py"))}


def imports(name: str, top_level_only: bool) -> list[tuple[str, list[str]]]:
    """(module imported, names taken from it) for each import statement of module ``name``; with
    ``top_level_only``, those that run when it is imported (not inside functions, nor under TYPE_CHECKING)."""
    path = MODULES[name]
    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    found = []

    def visit(nodes):
        for node in nodes:
            if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test) and top_level_only:
                visit(node.orelse)
            elif isinstance(node, ast.Import):
                found.extend((alias.name, []) for alias in node.names)
            elif isinstance(node, ast.ImportFrom):
                base = package[:len(package) - node.level + 1] if node.level else []
                module = ".".join(base + ([node.module] if node.module else []))
                for alias in node.names:
                    child = f"{module}.{alias.name}"
                    found.append((child, []) if child in MODULES else (module, [alias.name]))
            elif top_level_only and isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
                continue
            else:
                visit(ast.iter_child_nodes(node))

    visit(ast.parse(path.read_text()).body)
    return found


def test_an_import_only_points_down_from_the_simulators_to_labrig():
    wrong = [(name, target) for name in MODULES for target, _ in imports(name, top_level_only=False)
             if target.split(".")[0] in PACKAGES and target.split(".")[0] != name.split(".")[0]
             and target.split(".")[0] not in MAY_IMPORT[name.split(".")[0]]]
    assert not wrong, wrong


def test_no_module_imports_a_private_name_of_another():
    wrong = [(name, target, taken) for name in MODULES for target, names in imports(name, top_level_only=False)
             for taken in names if target.split(".")[0] in PACKAGES and target != name
             and taken.startswith("_") and not taken.startswith("__")]
    assert not wrong, wrong


def test_the_packages_have_no_import_cycle():
    """No group of modules imports itself round when they are imported (imports inside functions, which run
    later, and those only for the type checker do not count)."""
    graph = {name: {target for target, _ in imports(name, top_level_only=True) if target in MODULES} - {name}
             for name in MODULES}
    def reachable(start: str) -> set[str]:
        found, todo = set(), list(graph[start])
        while todo:
            node = todo.pop()
            if node not in found:
                found.add(node)
                todo.extend(graph[node])
        return found

    cycles = sorted(name for name in graph if name in reachable(name))  # every module on a way back to itself
    assert not cycles, cycles


def test_the_type_checker_covers_every_package_and_excuses_no_module():
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["mypy"]
    assert sorted(config["files"]) == sorted(PACKAGES)
    excused = [o["module"] for o in config.get("overrides", []) if o.get("ignore_errors")]
    assert not excused, f"modules excused from type checking: {excused}"


#: Modules kept under an old name for a deprecation period: one line, ``moved_module(__name__, NEW, ...)``.
MOVED = {name: found[1] for name, path in MODULES.items()
         if (found := re.search(r'^__getattr__, __dir__ = moved_module\(__name__, "([\w.]+)"', path.read_text(), re.M))}


def test_the_modules_that_moved_are_listed_and_import_by_their_old_names_with_a_warning():
    import importlib

    assert {"qdots.protocols", "qdots.micrograph.infer", "qdots.micrograph.write"} <= set(MOVED)
    stability = (ROOT / "docs" / "stability.md").read_text()
    for old, new in MOVED.items():
        assert f"`{old}`" in stability and f"`{new}`" in stability, f"docs/stability.md does not list {old}"
        sys.modules.pop(old, None)
        with pytest.warns(DeprecationWarning, match=rf"^{old} is {new} since 0\.3 .* goes in 0\.4$"):
            module = importlib.import_module(old)
        target = importlib.import_module(new)
        public = [n for n in vars(target) if not n.startswith("_")]
        assert public and all(getattr(module, n) is getattr(target, n) for n in public), old
        assert dir(module) == dir(target)


MEASURING_ALONE = textwrap.dedent("""
    import importlib, importlib.abc, sys

    class Blocked(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] in {"pymunk", "torch", "sbi"} or name.startswith("qdots.inference"):
                raise ModuleNotFoundError(f"{name} is blocked in this test", name=name)
            return None

    sys.meta_path.insert(0, Blocked())
    import qdots.micrograph as micrograph
    for name in sys.argv[1:]:
        importlib.import_module(name)
    for name in micrograph.__all__:
        getattr(micrograph, name)
    print("ok")
""")


def test_measuring_pictures_needs_neither_the_simulator_nor_the_inference():
    """qdots.micrograph, every module but the old names of moved ones, imports with pymunk, torch, sbi and
    qdots.inference unavailable (ARCHITECTURE.md); the inference builds on it, not the other way round."""
    measuring = [name for name in MODULES if name.startswith("qdots.micrograph.") and name not in MOVED]
    assert len(measuring) >= 15
    done = subprocess.run([sys.executable, "-c", MEASURING_ALONE, *measuring], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip().endswith("ok")


def test_the_search_by_colours_names_are_colour_bars_and_their_old_names_say_so():
    import qdots.micrograph.bar_profile as bar_profile
    import qdots.micrograph.colour_bars as colour_bars
    import qdots.micrograph.scale as scale

    for home, name in ((bar_profile, "half_contrast_length"), (colour_bars, "closed_lines"),
                       (bar_profile, "BAR_SURROUNDINGS"), (colour_bars, "tilted_bar")):
        with pytest.warns(DeprecationWarning, match=rf"scale.{name} is {home.__name__}.{name} .* 0\.4"):
            assert getattr(scale, name) is getattr(home, name)
    assert scale.colour_bar is colour_bars.colour_bar  # what the scale's search calls is imported, not moved away
    with pytest.raises(AttributeError, match="no attribute 'nothing'"):
        scale.nothing  # noqa: B018


def test_the_side_by_side_figure_is_the_inference_s_and_its_old_name_says_so():
    import qdots.inference.plots as plots
    import qdots.micrograph.overlay as overlay

    for name in ("save_side_by_side", "side_by_side_figure"):
        with pytest.warns(DeprecationWarning, match=rf"overlay.{name} is qdots.inference.plots.{name} .* 0\.4"):
            assert getattr(overlay, name) is getattr(plots, name)
    with pytest.raises(AttributeError, match="no attribute 'nothing'"):
        overlay.nothing  # noqa: B018
