"""The event engine's calendar: the dots' next events within a pass, earliest first (compiled).

Each dot has at most one scheduled event (`qdots.engine.event_loop`), and only events within the pass, up to its
end, can ever be resolved: the calendar holds those and forgets the others. It is Paul's calendar queue, one year
long: the pass is cut into as many equal days as there are dots, each day a doubly linked list of the dots whose
event falls on it. Putting a dot on its day, or taking it off, is a few writes; the next event is the earliest of
the first day that is not empty (a day holds a few events), and the days are swept once per pass, in order,
since no event is ever scheduled before the one being resolved. The earliest event is the same as in a binary
heap or a tournament tree: the smallest time, and among equal times the dot of lowest index (the day of a time
is a monotone function of it, so equal times share a day and an earlier time is never on a later day).

A calendar is one int64 array (`new_calendar`): the header (the pass's start and the length of a day, as the
bits of two floats, the number of days, the first day that may hold an event), then each day's first dot, then
each dot's day, previous and next dot on it (-1: none).
"""

from __future__ import annotations

import math

import numpy as np

from labrig.compiled import jit

#: Header slots: the pass's start (s) and 1 / day (1/s) as float64 bits, the number of days, the day swept to.
START, RATE, DAYS, SWEPT = 0, 1, 2, 3
HEADER = 4


@jit
def new_calendar(n, start, end):
    """An empty calendar for ``n`` dots over the pass from ``start`` to ``end`` s: ``max(n, 1)`` days."""
    days = max(n, 1)
    calendar = np.full(HEADER + days + 3 * n, -1, np.int64)
    floats = calendar[:2].view(np.float64)
    floats[START] = start
    floats[RATE] = days / (end - start) if end > start else 0.0
    calendar[DAYS] = days
    calendar[SWEPT] = 0
    return calendar


@jit(inline=True)
def _day_of(calendar, t):
    floats = calendar[:2].view(np.float64)
    day = int(math.floor((t - floats[START]) * floats[RATE]))
    return min(max(day, 0), calendar[DAYS] - 1)


@jit(inline=True)
def _slots(calendar, i):
    """Where dot ``i``'s day, previous and next dot are kept."""
    base = HEADER + calendar[DAYS] + 3 * i
    return base, base + 1, base + 2


@jit
def take_off(calendar, i):
    """Remove dot ``i``'s event from the calendar (nothing when it has none there)."""
    at, before, after = _slots(calendar, i)
    day = calendar[at]
    if day < 0:
        return
    prev = calendar[before]
    following = calendar[after]
    if prev >= 0:
        calendar[_slots(calendar, prev)[2]] = following
    else:
        calendar[HEADER + day] = following
    if following >= 0:
        calendar[_slots(calendar, following)[1]] = prev
    calendar[at] = -1
    calendar[before] = -1
    calendar[after] = -1


@jit
def put(calendar, i, t, end):
    """Dot ``i``'s event is now at ``t`` s: it is kept when ``t <= end`` (within the pass), else forgotten."""
    take_off(calendar, i)
    if not t <= end:
        return
    day = _day_of(calendar, t)
    at, before, after = _slots(calendar, i)
    first = calendar[HEADER + day]
    calendar[at] = day
    calendar[after] = first
    if first >= 0:
        calendar[_slots(calendar, first)[1]] = i
    calendar[HEADER + day] = i
    if day < calendar[SWEPT]:  # never in the engine (no event is scheduled before the one resolved); kept exact
        calendar[SWEPT] = day


@jit
def earliest(calendar, times):
    """The dot whose event is the earliest in the calendar (lowest index among equal times), or -1 if none."""
    days = calendar[DAYS]
    day = calendar[SWEPT]
    while day < days and calendar[HEADER + day] < 0:
        day += 1
    calendar[SWEPT] = day
    if day == days:
        return -1
    best = calendar[HEADER + day]
    k = calendar[_slots(calendar, best)[2]]
    while k >= 0:
        if times[k] < times[best] or (times[k] == times[best] and k < best):
            best = k
        k = calendar[_slots(calendar, k)[2]]
    return best
