import numpy as np
import pytest
from hypothesis import settings
from scipy.spatial import cKDTree

from labrig.tomlfile import toml_value

# Random tests never replay examples stored by an earlier run (a stored hang replayed for ever in one checkout):
# a failure hypothesis finds is turned into a plain regression test instead.
settings.register_profile("project", database=None)
settings.load_profile("project")


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


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


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


class TimeRecorder:
    """A writer for `qdots.Simulation.attach` that keeps the time of each state it is given, every ``every``
    steps."""

    def __init__(self, every: int):
        self.every = every
        self.times = []

    def write(self, state):
        self.times.append(state.time)


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
