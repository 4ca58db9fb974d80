"""Plain helpers the test files share: oracles, writers, file builders and the checks of a command's exit.

Pytest's fixtures and hooks are in conftest.py; this is an ordinary module. Test files import it as
``from helpers import ...``: pyproject's ``pythonpath`` puts tests/ on ``sys.path`` for the test files in
tests/labrig, tests/qdots and tests/planarize as for those at the top (no folder of tests has an
``__init__.py``), whether pytest runs from the repository root or as ``python -m pytest tests/...``.
"""

import re
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree

import qdots
from labrig.tomlfile import toml_value

GRAVITY_SCENE = """
name = "{name}"
[board]
width = 100.0
height = 100.0
[deposition]
n_dots = 12
interval = 0.0
settle = {settle}
[restitution]
wall = 0.0
[[forces]]
type = "Gravity"
"""


# -- oracles and boards ---------------------------------------------------------------------------

def has_avx512() -> bool:
    """Whether this CPU has AVX-512 (numpy's own record of its features; unknown counts as yes, so that a comparison
    is strict). Without it numpy's vectorized math takes other code paths that may round differently in the last
    bit, which the collisions of a polydisperse film amplify."""
    try:
        from numpy._core._multiarray_umath import __cpu_features__
    except ImportError:
        return True
    return bool(__cpu_features__.get("AVX512F", False))


def worst_overlap(positions, radii):
    """Worst (r_i + r_j - d) / ((r_i + r_j)/2) over all pairs (a test oracle, brute force for small N)."""
    positions = np.asarray(positions)
    pairs = cKDTree(positions).query_pairs(2 * radii.max(), output_type="ndarray")
    if not len(pairs):
        return 0.0
    i, j = pairs.T
    d = np.linalg.norm(positions[i] - positions[j], axis=1)
    rsum = radii[i] + radii[j]
    return max(0.0, float(((rsum - d) / (rsum / 2)).max()))


def lone_dot(velocity=(0.0, 0.0), mass=1.0, position=(1000.0, 1000.0)) -> qdots.Scene:
    """One dot of radius 5 px at ``position`` (px), moving at ``velocity`` (px/s), in a 2000 x 2000 px box."""
    return qdots.Scene(box=(2000.0, 2000.0), positions=[position], radii=[5.0], masses=[mass],
                       velocities=[velocity])


class TimeRecorder:
    """A writer for `qdots.Simulation.attach` that keeps the time of each state it is given, every ``every``
    steps."""

    def __init__(self, every: int):
        self.every = every
        self.times = []

    def write(self, state):
        self.times.append(state.time)


# -- files ------------------------------------------------------------------------------------------

def to_toml(tree: dict) -> str:
    """The text of a parameter file holding ``tree``: its values, then a ``[table]`` per dict and a
    ``[[table]]`` per dict of a list of dicts. A ValueError for a value TOML cannot hold."""
    lines, tables = [], []
    for key, value in tree.items():
        if isinstance(value, dict):
            tables.append((f"[{key}]", value))
        elif isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
            tables += [(f"[[{key}]]", item) for item in value]
        else:
            lines.append(f"{key} = {toml_value(value)}")
    for header, table in tables:
        lines.append(header)
        lines += [f"{k} = {toml_value(v)}" for k, v in table.items()]
    return "\n".join(lines) + "\n"


def gravity_scene_file(directory: Path, name: str = "grav", settle: float = 3.0) -> Path:
    """``directory/NAME.toml``: 12 dots dropped at once on a 100 x 100 px board under gravity onto an inelastic
    floor, left to settle ``settle`` s."""
    path = directory / f"{name}.toml"
    path.write_text(GRAVITY_SCENE.format(name=name, settle=settle))
    return path


def refused_file(load, path, content, match, **options) -> str:
    """Write ``content`` (text or bytes) to ``path``; ``load(path, **options)`` must raise a ValueError matching
    ``match`` whose message starts with the path. Returns the message."""
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content)
    with pytest.raises(ValueError, match=match) as error:
        load(path, **options)
    assert str(error.value).startswith(str(path))
    return str(error.value)


# -- command lines ----------------------------------------------------------------------------------

def one_line_error(capsys, prog="qdots"):
    """The ``PROG: error: ...`` line a refused command printed last (after any progress bars and stage lines, which
    also go to stderr): one line, no traceback."""
    return last_error_line(capsys.readouterr().err, prog)


#: A stage line of a run that took longer than a few seconds (`labrig.progress.StageLines`).
STAGE_LINE = re.compile(r"^\S+ \S+: .+ \(\d+ s.*\)$")


def last_error_line(err: str, prog="qdots") -> str:
    """The one ``PROG: error: ...`` line of ``err`` (a command's stderr), after any progress bars (redrawn in place)
    and stage lines; no traceback."""
    lines = err.strip().split("\r")[-1].splitlines()
    assert lines and "Traceback" not in err, err
    *before, last = lines
    assert last.startswith(f"{prog}: error:") and all(STAGE_LINE.match(line) for line in before), err
    return last


def run_ok(main, argv, capsys):
    """``main(argv)`` must exit 0; what it printed (``capsys.readouterr()``)."""
    assert main(argv) == 0
    return capsys.readouterr()


def refused_run(main, path, text, capsys, prog="qdots"):
    """``PROG run`` of a file holding ``text`` (results into ``out`` beside it): exit status 2 and a one-line
    error, returned."""
    path.write_text(text)
    assert main(["run", str(path), "--out", str(path.parent / "out")]) == 2
    return one_line_error(capsys, prog)


def refused(call, *words) -> str:
    """``call()`` raises `labrig.validate.InputError` in one line that holds every one of ``words``; its message."""
    from labrig.validate import InputError

    with pytest.raises(InputError) as caught:
        call()
    message = str(caught.value)
    assert "\n" not in message, message
    for word in words:
        assert word in message, (word, message)
    return message


def disc_film_png(path, n=60, size=240, diameter=16.0, sigma=0.05, seed=3, noise=10.0):
    """Write a film of ``n`` dark flat discs (placed at random, ``diameter`` px apart at least, spread ``sigma``) on a
    ``size`` px square support with Gaussian noise, as a PNG; returns the true centres ``(x, y)``, px."""
    from PIL import Image

    from qdots.placement import random_sequential

    centres = random_sequential(n, (size, size), diameter, sigma, rng=seed)[0]
    yy, xx = np.mgrid[:size, :size]
    picture = np.full((size, size), 200.0)
    for x, y in centres:
        picture[(xx - x) ** 2 + (yy - y) ** 2 <= (diameter / 2) ** 2] = 60
    picture += np.random.default_rng(seed).normal(scale=noise, size=picture.shape)
    Image.fromarray(np.clip(picture, 0, 255).astype(np.uint8)).save(path)
    return np.asarray(centres)
