"""Surface: validation, exact volume, refinement, scenes."""

import numpy as np
import pytest

from planarize import Surface, surfaces
from planarize.heightfield import volume_weights


def triangle_volume(surface: Surface) -> float:
    """Volume under the 4-triangles-per-cell surface, summed triangle by triangle (independent oracle).

    The volume under a planar triangle is its projected area times the mean of its vertex heights.
    """
    z = surface.z
    if surface.periodic:
        z = np.pad(z, ((0, 1), (0, 1)), mode="wrap")
    a, b, c, d = z[:-1, :-1], z[1:, :-1], z[1:, 1:], z[:-1, 1:]
    centre = (a + b + c + d) / 4
    quarter = surface.dx * surface.dy / 4
    total = 0.0
    for p, q in ((a, b), (b, c), (c, d), (d, a)):
        total += np.sum(quarter * (p + q + centre) / 3)
    return float(total)


@pytest.mark.parametrize("bad, message", [
    (np.array([1.0, 2.0]), "2-D"),
    (np.zeros((1, 5)), "at least 2 x 2"),
    (np.array([[0.0, np.nan], [0.0, 0.0]]), "non-finite"),
    (np.array([[0.0, np.inf], [0.0, 0.0]]), "non-finite"),
    ([["a", "b"], ["c", "d"]], "real numbers"),
])
def test_bad_heights_are_named(bad, message):
    with pytest.raises(ValueError, match=message):
        Surface(bad)


@pytest.mark.parametrize("spacing", [0.0, -1.0, np.nan, (1.0, 0.0), (1.0, 2.0, 3.0), "x"])
def test_bad_spacing(spacing):
    with pytest.raises(ValueError, match="spacing"):
        Surface(np.zeros((3, 3)), spacing)


def test_bad_boundary():
    with pytest.raises(ValueError, match="boundary"):
        Surface(np.zeros((3, 3)), boundary="wrap")


def test_surface_is_immutable_copy():
    z = np.zeros((3, 3))
    s = Surface(z)
    z[0, 0] = 5.0
    assert s.z[0, 0] == 0.0
    with pytest.raises(ValueError):
        s.z[0, 0] = 1.0


@pytest.mark.parametrize("boundary", ["open", "periodic"])
def test_volume_is_exact_for_the_triangulated_surface(boundary, rng):
    s = Surface(rng.uniform(-1, 3, (7, 9)), (0.3, 0.7), boundary)
    assert s.volume() == pytest.approx(triangle_volume(s), rel=1e-13)
    # the thesis's "area times mean height" only holds on a periodic grid
    area_times_mean = s.size[0] * s.size[1] * s.z.mean()
    if boundary == "periodic":
        assert s.volume() == pytest.approx(area_times_mean, rel=1e-13)
    else:
        assert abs(s.volume() - area_times_mean) > 1e-6 * abs(s.volume())


def test_volume_is_linear_in_each_height():
    """Moving one point by dz changes the volume by its weight times dz (thesis Eq 3.4, corrected)."""
    s = Surface(np.zeros((5, 4)), (0.5, 2.0))
    w = volume_weights(s.shape, s.dx, s.dy)
    for i, j in [(0, 0), (0, 2), (2, 1), (4, 3)]:
        z = np.zeros(s.shape)
        z[i, j] = 1.0
        assert s.with_heights(z).volume() == pytest.approx(w[i, j], rel=1e-14)
        assert triangle_volume(s.with_heights(z)) == pytest.approx(w[i, j], rel=1e-14)
    assert w[0, 0] == 0.25 and w[0, 1] == 0.5 and w[1, 1] == 1.0


def test_linear_refinement_keeps_points_and_planes(rng):
    plane = Surface(1.0 + 0.3 * np.arange(5)[:, None] - 0.2 * np.arange(4)[None, :], 1.0)
    fine = plane.refine(4)
    assert fine.shape == (17, 13) and fine.dx == 0.25
    x, y = np.meshgrid(fine.x, fine.y, indexing="ij")
    np.testing.assert_allclose(fine.z, 1.0 + 0.3 * x - 0.2 * y, atol=1e-13)
    rough = Surface(rng.normal(size=(4, 6)), 1.0)
    np.testing.assert_array_equal(rough.refine(3).z[::3, ::3], rough.z)


def test_cubic_refinement_reproduces_cubics_and_is_smooth():
    x = np.arange(6.0)
    cubic = Surface(np.add.outer(0.1 * x**3 - x, 0.05 * x**2), 1.0)
    fine = cubic.refine(4, "cubic")
    xf = fine.x
    np.testing.assert_allclose(fine.z, np.add.outer(0.1 * xf**3 - xf, 0.05 * xf**2), atol=1e-12)
    bump = surfaces.hill(refine=1).refine(8, "cubic")
    linear = surfaces.hill(refine=1).refine(8, "linear")
    # linear refinement leaves slope jumps (creases) at the old grid lines; cubic does not
    def largest_curvature(s):
        return float(np.abs(np.diff(s.z, 2, axis=0)).max())
    assert largest_curvature(bump) < 0.5 * largest_curvature(linear)


def test_periodic_refinement_wraps():
    n = 8
    z = np.sin(2 * np.pi * np.arange(n) / n)[:, None] * np.ones((1, 4))
    fine = Surface(z, 1.0, "periodic").refine(4, "cubic")
    assert fine.shape == (32, 16)
    exact = np.sin(2 * np.pi * fine.x / n)[:, None]
    assert np.abs(fine.z - exact).max() < 5e-3


@pytest.mark.parametrize("factor", [0, -2, 1.5, True])
def test_bad_refinement(factor):
    with pytest.raises(ValueError, match="factor"):
        Surface(np.zeros((3, 3))).refine(factor)
    with pytest.raises(ValueError, match="method"):
        Surface(np.zeros((3, 3))).refine(2, "quintic")


def test_thesis_scenes():
    hill, dep = surfaces.hill(), surfaces.depression()
    assert hill.shape == (17, 17) and hill.dx == 0.25
    assert hill.z.max() == 4.5 and hill.z.min() == 4.0
    np.testing.assert_allclose(dep.z, 8.0 - hill.z)
    # the linear refinement makes a pyramid 2 nm wide (8 grid points)
    assert np.count_nonzero(hill.z[8] > 4.0) == 7
    ta = surfaces.random_roughness(seed=3)
    assert ta.shape == (101, 101) and ta.dx == 5.0
    assert abs(ta.z.mean() - 1000.0) < 5.0 and ta.z.max() - ta.z.min() < 50.0
    assert surfaces.random_roughness(seed=3) == ta and surfaces.random_roughness(seed=4) != ta
    periodic = surfaces.random_roughness(size=200, boundary="periodic", seed=1)
    assert periodic.shape == (40, 40) and periodic.periodic


@pytest.mark.parametrize("call, message", [
    (lambda: surfaces.bump(points=4), "odd"),
    (lambda: surfaces.bump(spacing=-1), "spacing"),
    (lambda: surfaces.random_roughness(size=250), "whole number"),
    (lambda: surfaces.random_roughness(scales=[(200, 30), (30, 5)]), "divide"),
    (lambda: surfaces.random_roughness(scales=[]), r"scales must be a list of at most 64 \[number, number\] pairs, .*got \[\]"),
    (lambda: surfaces.random_roughness(size=100, boundary="periodic"), "at least two"),
    (lambda: surfaces.tilted_plane(slope=(np.nan, 0)), "slope must be 2 numbers"),
])
def test_bad_scene_parameters(call, message):
    with pytest.raises(ValueError, match=message):
        call()


def test_a_refinement_factor_out_of_range_says_what_it_is_and_the_range():
    surface = surfaces.hill()
    for factor in (0, -1, 4097, 1.5, True):
        with pytest.raises(ValueError) as error:
            surface.refine(factor)
        assert str(error.value) == (f"factor (grid steps each split into this many) must be an integer in [1, 4,096], "
                                    f"got {factor!r}")
