"""The event engine's calendar gives the earliest event as a sort would (smallest time, then lowest index), and the
wall test it skips is one a dot could not pass."""

import math

import numpy as np
import pytest

from qdots.engine.event_calendar import earliest, new_calendar, put, take_off
from qdots.engine.event_loop import near_walls, wall_time


def expected_first(times: dict) -> int:
    """The dot of the earliest time among those kept, lowest index first (-1: none)."""
    return min(times, key=lambda i: (times[i], i)) if times else -1


@pytest.mark.parametrize("seed", range(4))
def test_the_calendar_gives_what_a_sort_gives(seed):
    """Random puts, removals and pops (ties made often by drawing times from a few values, events beyond the
    pass's end forgotten), each earliest event checked against a sort."""
    rng = np.random.default_rng(seed)
    n, start, end = 50, 1.0, 1.02
    times = np.full(n, math.inf)
    calendar = new_calendar(n, start, end)
    kept: dict[int, float] = {}
    now = start
    for _ in range(2000):
        i = int(rng.integers(n))
        op = rng.random()
        if op < 0.6:  # (re)schedule dot i at or after now, sometimes beyond the end, often on a tied time
            t = now + (rng.choice([0.0, 1e-3, 2e-3]) if rng.random() < 0.5 else rng.uniform(0.0, 0.03))
            times[i] = t
            put(calendar, i, t, end)
            if t <= end:
                kept[i] = t
            else:
                kept.pop(i, None)
        elif op < 0.7:
            take_off(calendar, i)
            kept.pop(i, None)
        else:  # resolve the earliest: time moves on to it
            first = earliest(calendar, times)
            assert first == expected_first(kept)
            if first >= 0:
                now = times[first]
                take_off(calendar, first)
                del kept[first]
    while kept:
        first = earliest(calendar, times)
        assert first == expected_first(kept)
        take_off(calendar, first)
        del kept[first]
    assert earliest(calendar, times) == -1


def test_equal_times_go_to_the_lowest_index_and_the_end_is_kept():
    times = np.array([0.5, 0.25, 0.25, 1.0])
    calendar = new_calendar(4, 0.0, 1.0)
    for i in (3, 2, 1, 0):
        put(calendar, i, times[i], 1.0)
    order = []
    while (i := earliest(calendar, times)) >= 0:
        order.append(i)
        take_off(calendar, i)
    assert order == [1, 2, 0, 3]  # the event at exactly the pass's end is within it


def test_a_dot_out_of_reach_of_every_wall_would_not_touch_one():
    """`near_walls` leaves out only dots that cannot reach a wall in the pass: such a dot's wall times lie beyond
    the pass at any speed up to the bound, and dots within reach are flagged."""
    rng = np.random.default_rng(0)
    walls = np.array([[0.0, 0.0, 400.0, 0.0], [400.0, 0.0, 400.0, 400.0], [0.0, 400.0, 0.0, 0.0],
                      [100.0, 150.0, 250.0, 260.0]])
    x, y = rng.uniform(-20.0, 420.0, 5000), rng.uniform(-20.0, 420.0, 5000)
    radii = rng.uniform(4.0, 9.0, x.size)
    bound, seconds, margin = 200.0, 0.02, 1.0
    near = near_walls(x, y, radii, bound * seconds + margin, walls)
    assert 0 < near.sum() < x.size
    angle = rng.uniform(0.0, 2.0 * math.pi, x.size)
    for k in np.flatnonzero(~near):
        vx, vy = bound * math.cos(angle[k]), bound * math.sin(angle[k])
        for w in walls:
            assert wall_time(x[k], y[k], vx, vy, radii[k], *w)[0] > seconds
    segment = np.array([[0.0, 0.0, 100.0, 0.0]])
    close = near_walls(np.array([50.0, 50.0]), np.array([7.5 + 4.9, 7.5 + 5.1 + 1.0]), np.full(2, 7.5), 5.0, segment)
    assert close.tolist() == [True, False]
