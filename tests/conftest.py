"""Pytest's fixtures shared by several test files, and the hypothesis profile (plain helpers: helpers.py)."""

import numpy as np
import pytest
from hypothesis import settings

import qdots

# Random tests never replay examples stored by an earlier run (a stored hang replayed for ever in one checkout):
# a failure hypothesis finds is turned into a plain regression test instead.
settings.register_profile("project", database=None)
settings.load_profile("project")


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


@pytest.fixture(scope="module")
def good_state(tmp_path_factory):
    """A qdots state file: two dots 40 px apart in a 100 x 100 px box after 0.05 s of thermal kicks."""
    path = tmp_path_factory.mktemp("state") / "good.npz"
    scene = qdots.Scene(box=(100, 100), positions=[[30, 50], [70, 50]], radii=[7.5, 7.5])
    sim = qdots.Simulation(scene, [qdots.ThermalKicks()], seed=1)
    sim.run(0.05)
    qdots.save(sim, path)
    return path
