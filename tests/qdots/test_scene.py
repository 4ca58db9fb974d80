"""Scene and collision-rule validation: every bad input is a ValueError naming the field (and the index); so is
a value of the wrong type given to the Python API (Scene, Restitution, Simulation)."""

import numpy as np
import pytest

import qdots
from qdots.scene import grating_segments


def two_dots(**changes):
    fields = dict(box=(100, 100), positions=[[30, 50], [70, 50]], radii=[7.5, 7.5])
    fields.update(changes)
    return qdots.Scene(**fields)


def test_valid_scene_defaults():
    scene = two_dots()
    assert scene.n_dots == 2
    np.testing.assert_array_equal(scene.masses, [1, 1])
    np.testing.assert_array_equal(scene.velocities, np.zeros((2, 2)))
    assert scene.wall_segments().shape == (4, 4)
    assert not scene.positions.flags.writeable


@pytest.mark.parametrize(
    "changes, message",
    [
        (dict(radii=[7.5, -1.0]), r"radii\[1\] = -1.0 must be in \(0, "),
        (dict(radii=[0.0, 7.5]), r"radii\[0\] = 0.0 must be in \(0, "),
        (dict(radii=[7.5, np.nan]), r"radii\[1\] is not finite"),
        (dict(positions=[[30, 50], [np.nan, 50]]), r"positions\[1\] is not finite"),
        (dict(positions=[[30, 50], [np.inf, 50]]), r"positions\[1\] is not finite"),
        (dict(masses=[1.0, 0.0]), r"masses\[1\] = 0.0 must be in \(0, "),
        (dict(masses=[-2.0, 1.0]), r"masses\[0\] = -2.0 must be in \(0, "),
        (dict(velocities=[[0, 0], [0, np.nan]]), r"velocities\[1\] is not finite"),
        (dict(positions=[[30, 50], [40, 50]]), r"dots 0 and 1 overlap"),
        (dict(positions=[[30, 50], [95, 50]]), r"positions\[1\] = \(95, 50\) with radius 7.5 lies outside the box"),
        (dict(positions=[[5, 50], [70, 50]]), r"positions\[0\] .* lies outside the box"),
        (dict(radii=[7.5]), r"radii must have shape \(2,\)"),
        (dict(positions=[1, 2, 3]), r"positions must have shape \(N, 2\)"),
        (dict(box=(100, -5)), r"box\[1\] = -5.0 must be in \(0, "),
        (dict(segments=[[10, 10, 10, 10]]), r"segments\[0\] has zero length"),
        (dict(radii=["a", "b"]), r"radii must hold real numbers"),
    ],
)
def test_bad_input_is_named(changes, message):
    with pytest.raises(ValueError, match=message):
        two_dots(**changes)


def test_overlap_names_the_worst_pair():
    positions = [[20, 50], [34, 50], [60, 50], [70, 50]]  # 0-1 overlap by 1 px, 2-3 by 5 px
    with pytest.raises(ValueError, match=r"dots 2 and 3 overlap"):
        qdots.Scene(box=(100, 100), positions=positions, radii=[7.5] * 4)


def test_overlap_tolerance_accepts_soft_contacts_only():
    positions = [[30, 50], [44.9, 50]]  # relative overlap 0.1 / 7.5 = 1.33 %
    with pytest.raises(ValueError, match="relative overlap 0.0133"):
        qdots.Scene(box=(100, 100), positions=positions, radii=[7.5, 7.5])
    qdots.Scene(box=(100, 100), positions=positions, radii=[7.5, 7.5], overlap_tolerance=0.02)
    with pytest.raises(ValueError, match="overlap"):
        qdots.Scene(box=(100, 100), positions=positions, radii=[7.5, 7.5], overlap_tolerance=0.01)
    with pytest.raises(ValueError, match="overlap_tolerance must be in"):
        qdots.Scene(box=(100, 100), positions=positions, radii=[7.5, 7.5], overlap_tolerance=-0.1)


def test_touching_dots_are_allowed():
    qdots.Scene(box=(100, 100), positions=[[30, 50], [45, 50]], radii=[7.5, 7.5])


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(mean=1.2), r"Restitution.mean must be in \[0, 1\]"),
        (dict(wall=-0.1), r"Restitution.wall must be in \[0, 1\]"),
        (dict(sticking_speed=-1), r"sticking_speed must be in \[0, "),
    ],
)
def test_restitution_validation(kwargs, message):
    with pytest.raises(ValueError, match=message):
        qdots.Restitution(**kwargs)


def test_the_collision_rule_is_the_simulations_not_the_scenes():
    """A scene says what exists; the rule is given to (and checked by) the simulation, at start and between runs."""
    with pytest.raises(TypeError, match="restitution"):
        two_dots(restitution=qdots.Restitution())
    with pytest.raises(ValueError, match=r"restitution must be a qdots.Restitution, got float"):
        qdots.Simulation(two_dots(), restitution=0.8)
    sim = qdots.Simulation(two_dots(), restitution=qdots.Restitution(mean=0.5), seed=0)
    assert sim.restitution == qdots.Restitution(mean=0.5)
    with pytest.raises(ValueError, match=r"restitution must be a qdots.Restitution, got float"):
        sim.restitution = 0.8
    assert sim.restitution == qdots.Restitution(mean=0.5)


def test_restitution_spread_follows_thesis():
    assert qdots.Restitution(mean=0.8).std == pytest.approx(0.1)
    assert qdots.Restitution(mean=0.3).std == pytest.approx(0.15)
    assert qdots.Restitution(mean=1.0).std == 0.0


def test_open_box_has_only_extra_segments():
    scene = two_dots(closed=False, segments=[[0, 20, 100, 20]])
    np.testing.assert_array_equal(scene.wall_segments(), [[0, 20, 100, 20]])


def test_grating_lines():
    pitch = 6 * 15 * np.sqrt(3) / 2
    lines = grating_segments((600, 600), pitch)
    np.testing.assert_allclose(lines[:, 1], pitch * np.arange(1, len(lines) + 1))
    assert lines[:, 1].max() < 600 and len(lines) == int(600 // pitch)
    with pytest.raises(ValueError, match="pitch"):
        grating_segments((600, 600), 0)


def test_replace_revalidates():
    with pytest.raises(ValueError, match="radii"):
        two_dots().replace(radii=[7.5, -7.5])


def test_api_type_errors_name_the_field():
    scene = qdots.Scene(box=(100, 100), positions=[[50, 50]], radii=[7.5])
    for call, field in ((lambda: qdots.Restitution(mean="x"), "Restitution.mean"),
                        (lambda: qdots.Simulation(scene, collision_bias="x"), "collision_bias"),
                        (lambda: qdots.Simulation(scene, seed=-1), "seed"),
                        (lambda: qdots.Simulation(scene, dt="fast"), "dt"),
                        (lambda: qdots.Simulation(scene, pair_skin="x"), "pair_skin"),
                        (lambda: qdots.Scene(box=(100, 100), positions=[[50, 50]], radii=[7.5], closed=1), "closed")):
        with pytest.raises(ValueError, match=field):
            call()
