"""Hard cases for the planarization engines: cliffs, spikes, tilted planes, very low and high k_exp.

Every case must finish with finite heights, the oxide nowhere below the metal and non-negative
distances; the thesis's engines keep the volume balance exact to round-off, the continuum engine
states its error, volume balance included (or names the quantities that do not converge steadily and states
none for them), and says when it does not meet its tolerance.
"""

import numpy as np
import pytest

from planarize import Model, Surface, anodize, surfaces


def assert_sane(run):
    for shot in run.snapshots:
        assert np.all(np.isfinite(shot.metal.z)) and np.all(np.isfinite(shot.oxide.z))
        assert np.all(shot.oxide.z >= shot.metal.z)
        assert np.all(np.isfinite(shot.distances)) and np.all(shot.distances >= 0)
    if run.parameters["engine"] == "continuum":
        p = run.parameters
        largest = np.abs(run.history["volume_error"]).max()
        assert p["volume_error"] == largest
        # an error is stated, or the quantities that do not converge steadily are named (and none is claimed)
        assert np.isfinite(p["estimated_error"]) != bool(p["not_asymptotic"])
        assert p["rtol_met"] == bool(np.isfinite(p["estimated_error"]) and max(p["estimated_error"], largest) <= p["rtol"])
    else:
        assert np.all(np.abs(run.history["volume_error"]) < 1e-12)
    assert run.thickness >= run.parameters["thickness"]


def hard_surface(kind: str) -> Surface:
    z = np.full((8, 8), 4.0)
    if kind == "cliff":
        z[:, 4:] = 7.0  # a 3 nm wall between two grid columns 0.25 nm apart
    elif kind == "spike":
        z[3, 4] = 9.0
    elif kind == "pit":
        z[3, 4] = 0.0
    elif kind == "checkerboard":
        z += 0.5 * ((np.add.outer(np.arange(8), np.arange(8)) % 2) - 0.5)
    return Surface(z, 0.25)


@pytest.mark.parametrize("engine", ["continuum", "fast"])
@pytest.mark.parametrize("k_exp", [1.05, 5.0])
@pytest.mark.parametrize("kind", ["cliff", "spike", "pit", "checkerboard"])
def test_rough_surfaces_at_extreme_expansion(kind, k_exp, engine):
    run = anodize(hard_surface(kind), 0.5, record=4, snapshots=[0.0, 0.25, 0.5], model=Model(step=0.02, k_exp=k_exp),
                  engine=engine)
    assert_sane(run)


@pytest.mark.parametrize("engine", ["reference", "fast"])
def test_spike_in_periodic_exact_distances(engine):
    z = np.full((7, 7), 4.0)
    z[0, 0] = 7.0  # on the seam of the periodic grid
    run = anodize(Surface(z, 0.25, "periodic"), 0.4, record=3, model=Model(step=0.02, distance="exact"), engine=engine)
    assert_sane(run)
    # the spike is cut down: its metal height drops much more than the flat film's
    assert 7.0 - run.metal.z[0, 0] > 5 * (4.0 - np.median(run.metal.z))


@pytest.mark.parametrize("engine", ["continuum", "fast"])
@pytest.mark.parametrize("slope", [(0.2, 0.0), (0.5, -0.3), (3.0, 0.0)])
def test_tilted_planes_stay_planes(slope, engine):
    """A tilted plane has nothing to planarize: away from the edges both surfaces stay planes of the same slope.

    (Within about the oxide thickness of an open edge the surfaces bend: the oxide there lacks the
    neighbours beyond the edge, the thesis's finite-sample effect.)
    """
    plane = surfaces.tilted_plane(slope, points=21)
    run = anodize(plane, 0.5, record=3, model=Model(step=0.01), engine=engine)
    assert_sane(run)
    x, y = np.meshgrid(plane.x, plane.y, indexing="ij")
    margin = 1.5
    inside = ((x > margin) & (x < plane.x[-1] - margin) & (y > margin) & (y < plane.y[-1] - margin)).ravel()
    design = np.column_stack([x.ravel(), y.ravel(), np.ones(x.size)])[inside]
    tilt = 1 + np.hypot(*slope)
    for z in (run.metal.z, run.oxide.z):
        coef, *_ = np.linalg.lstsq(design, z.ravel()[inside], rcond=None)
        residual = z.ravel()[inside] - design @ coef
        assert np.abs(residual).max() < 2 * 0.01 * tilt  # within two steps
        np.testing.assert_allclose(coef[:2], slope, atol=0.01 * tilt)


@pytest.mark.parametrize("engine", [pytest.param("continuum", marks=pytest.mark.slow), "fast"])  # (continuum: 17 s)
def test_very_steep_random_surface(engine):
    rng = np.random.default_rng(11)
    run = anodize(Surface(rng.uniform(0, 3, (9, 9)), 0.25), 0.5, record=3,
                  model=Model(step=0.05, k_exp=2.3, distance="exact"), engine=engine)
    assert_sane(run)
    if engine == "continuum":  # slopes of 12: the flow's volume balance is far from exact, and it says so
        assert not run.parameters["rtol_met"] and run.parameters["volume_error"] > 0.05
