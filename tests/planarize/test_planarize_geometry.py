"""Distances (thesis Eq 3.5, 3.6, and the exact point-triangle distance) against independent oracles."""

import numpy as np
import pytest
from scipy.optimize import minimize

from planarize.geometry import point_point, point_segment, point_triangle


def segment_oracle(p, a, b) -> float:
    """Ternary search along the segment (the distance is convex in the position)."""
    lo, hi = 0.0, 1.0
    f = lambda t: np.linalg.norm(p - (a + t * (b - a)))  # noqa: E731
    for _ in range(200):
        m1, m2 = lo + (hi - lo) / 3, hi - (hi - lo) / 3
        if f(m1) < f(m2):
            hi = m2
        else:
            lo = m1
    return min(f(0.5 * (lo + hi)), f(0.0), f(1.0))


def triangle_oracle(p, a, b, c) -> float:
    """Constrained minimisation over barycentric coordinates, from several starts."""
    def f(w):
        q = a + w[0] * (b - a) + w[1] * (c - a)
        return float(np.sum((p - q) ** 2))
    cons = [{"type": "ineq", "fun": lambda w: w[0]}, {"type": "ineq", "fun": lambda w: w[1]},
            {"type": "ineq", "fun": lambda w: 1 - w[0] - w[1]}]
    best = min(minimize(f, x0, constraints=cons, method="SLSQP", options={"ftol": 1e-15, "maxiter": 500}).fun
               for x0 in ([0.3, 0.3], [0.9, 0.05], [0.05, 0.9], [0.05, 0.05]))
    edges = [segment_oracle(p, a, b), segment_oracle(p, b, c), segment_oracle(p, c, a)]
    return min(np.sqrt(max(best, 0.0)), *edges)


def test_point_point():
    assert point_point([0, 0, 0], [3, 4, 12]) == 13.0
    np.testing.assert_allclose(point_point(np.zeros((5, 3)), np.ones(3)), np.sqrt(3))


def test_point_segment_against_oracle(rng):
    p, a, b = rng.normal(size=(3, 200, 3))
    d, t = point_segment(p, a, b)
    oracle = [segment_oracle(*x) for x in zip(p, a, b)]
    np.testing.assert_allclose(d, oracle, atol=1e-9)
    # t locates the closest point
    np.testing.assert_allclose(np.linalg.norm(p - (a + t[:, None] * (b - a)), axis=1), d, atol=1e-12)


def test_point_segment_cases():
    # the thesis's Eq 3.6: perpendicular distance when the foot is inside
    d, t = point_segment([0.5, 1.0, 0.0], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0])
    assert d == pytest.approx(1.0) and t == pytest.approx(0.5)
    # beyond an end: the end point, and t is exactly 0 or 1
    d, t = point_segment([-1.0, 1.0, 0.0], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0])
    assert d == pytest.approx(np.sqrt(2)) and t == 0.0
    d, t = point_segment([3.0, 0.0, 4.0], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0])
    assert d == pytest.approx(np.sqrt(4 + 16)) and t == 1.0
    # straight above an end: t is exactly 0, so the thesis's engine leaves it to the point-point pair
    d, t = point_segment([0.0, 0.0, 2.0], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0])
    assert t == 0.0 and d == 2.0
    # degenerate segment
    d, t = point_segment([1.0, 1.0, 1.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0])
    assert d == pytest.approx(np.sqrt(3)) and t == 0.0


def test_point_triangle_against_oracle(rng):
    p, a, b, c = rng.normal(size=(4, 60, 3))
    d, w = point_triangle(p, a, b, c)
    oracle = [triangle_oracle(*x) for x in zip(p, a, b, c)]
    np.testing.assert_allclose(d, oracle, atol=1e-6)
    assert np.all(w >= 0) and np.allclose(w.sum(axis=1), 1.0)
    closest = w[:, :1] * a + w[:, 1:2] * b + w[:, 2:] * c
    np.testing.assert_allclose(np.linalg.norm(p - closest, axis=1), d, atol=1e-12)


def test_point_triangle_face_and_weights():
    a, b, c = np.array([0.0, 0, 0]), np.array([1.0, 0, 0]), np.array([0.0, 1, 0])
    d, w = point_triangle([0.25, 0.25, 2.0], a, b, c)
    assert d == pytest.approx(2.0)
    np.testing.assert_allclose(w, [0.5, 0.25, 0.25])
    # outside across an edge: that edge's weights, the opposite corner's weight exactly 0
    d, w = point_triangle([0.5, -1.0, 0.0], a, b, c)
    assert d == pytest.approx(1.0) and w[2] == 0.0
    # outside at a corner: one weight 1
    d, w = point_triangle([2.0, -1.0, 0.0], a, b, c)
    assert d == pytest.approx(np.sqrt(2)) and w[1] == 1.0


@pytest.mark.parametrize("corners", [
    ([0.0, 0, 0], [1.0, 0, 0], [2.0, 0, 0]),      # collinear
    ([0.0, 0, 0], [0.0, 0, 0], [1.0, 1, 1]),      # two coincide
    ([0.5, 0.5, 0.5], [0.5, 0.5, 0.5], [0.5, 0.5, 0.5]),  # a point
    ([0.0, 0, 0], [1.0, 1e-13, 0], [2.0, 0, 0]),  # nearly collinear
])
def test_degenerate_triangles_are_their_edges(corners, rng):
    a, b, c = (np.array(x) for x in corners)
    for p in rng.normal(size=(20, 3)):
        d, w = point_triangle(p, a, b, c)
        assert np.isfinite(d) and np.all(np.isfinite(w))
        edges = min(segment_oracle(p, a, b), segment_oracle(p, b, c), segment_oracle(p, c, a))
        assert d == pytest.approx(edges, abs=1e-9)
