"""The thesis's event-driven hard discs, compiled: every collision of a frame found and resolved exactly, in
time order (section 2.2, steps 4-11).

Within a frame the dots move in straight lines (the forces changed their velocities at the frame's start,
steps 1-3). Each dot has one next event: the earliest contact with a candidate neighbour or a wall, its
discs widened by the buffer (the thesis adds a millionth of the mean radius to every radius, so dots
resolved at contact stay that far apart and round-off never makes them overlap). The earliest event of
all (`qdots.engine.event_calendar`) is resolved: the two discs are moved to its time (each dot keeps
its own time stamp; the others move only when needed, which is exact in straight lines, where the thesis
moved every dot to each collision), their velocities change by Eq 2.5 (`impact_elasticity`) or by the
wall's restitution, and their next events are found again. A dot whose scheduled partner has collided
since is rescheduled when its stale event comes up (its own path did not change, so nothing earlier can
have been missed). The frame ends when the next event lies beyond it, or after ``max_events`` events
(the thesis's cap: the rest of the frame is then not moved, as its loop did); every dot is then moved to
the frame's end.

Simultaneous events (equal times to the last bit, as when a dot rests against two neighbours at once) are
resolved in the order of the dots' indices: a dot's earliest contact is with its partner of lowest index, and
the earliest event of all is that of the dot of lowest index, so a frame's result does not depend on the order
in which the candidates were found.

Candidate neighbours are the pairs that can touch within the frame at the speeds they may reach
(`qdots.engine.event_backend`); a collision that makes some dot faster than that bound ends the pass early and
the caller builds the candidates again from that moment, so no contact is missed. A dot tests the walls only when
it starts the pass within reach of one at that speed (`near_walls`).

During a pass the dots' state is kept as one row per dot (position, velocity, time stamp, radius, inverse mass,
collisions in the pass: `STATE_COLUMNS`), so that a neighbour's test reads one cache line.
"""

from __future__ import annotations

import math

import numpy as np

from labrig.compiled import jit

from .contacts import DOT_WALL, RESTING, WALL_ELASTICITY, impact_elasticity
from .event_calendar import earliest, new_calendar, put

#: Why `advance_events` returned: the frame is done, the event cap was reached, or a dot got faster than
#: the candidates were built for (the caller rebuilds them and goes on).
DONE, CAPPED, REBUILD = 0, 1, 2
#: No event.
NEVER = math.inf
#: Columns of a dot's row in a pass (`advance_events`).
X, Y, VX, VY, STAMP, RADIUS, INV_MASS, COUNT = range(8)
STATE_COLUMNS = 8
#: Extra distance, px, at which a dot still tests a wall it cannot reach in a pass (round-off margin).
WALL_MARGIN = 1.0


@jit(inline=True)
def pair_time(dx, dy, dvx, dvy, sigma):
    """Time until two discs whose centres are ``(dx, dy)`` apart (px, from the first to the second) and close
    at ``(dvx, dvy)`` (px/s, the second's velocity less the first's) come within ``sigma`` px; 0 when they are
    already that close and approaching, inf when they never do (or close more slowly than
    `qdots.engine.contacts.RESTING`: within a frame they would close by far less than the buffer)."""
    b = dx * dvx + dy * dvy
    if b >= 0.0 or b >= -RESTING * math.sqrt(dx * dx + dy * dy):  # parting pairs skip the square root
        return NEVER
    c = dx * dx + dy * dy - sigma * sigma
    if c <= 0.0:
        return 0.0
    a = dvx * dvx + dvy * dvy
    disc = b * b - a * c
    if disc <= 0.0:
        return NEVER
    return c / (-b + math.sqrt(disc))  # the smaller root of a t^2 + 2 b t + c, without cancellation


@jit(inline=True)
def wall_time(x, y, vx, vy, reach, x0, y0, x1, y1):
    """``(t, nx, ny, ex, ey)``: time until a disc of radius ``reach`` at ``(x, y)`` moving at ``(vx, vy)`` touches
    the segment, the segment's unit normal on the disc's side and its end touched (nan when it is the line).
    ``t`` is inf when it never does."""
    ex = x1 - x0
    ey = y1 - y0
    length = math.sqrt(ex * ex + ey * ey)
    ux = ex / length
    uy = ey / length
    nx = -uy
    ny = ux
    s = (x - x0) * nx + (y - y0) * ny
    if s < 0.0:
        nx = -nx
        ny = -ny
        s = -s
    best = NEVER
    bx = math.nan
    by = math.nan
    vn = vx * nx + vy * ny
    if vn < 0.0:  # closing on the line
        t = max(0.0, (s - reach) / -vn)
        along = (x + vx * t - x0) * ux + (y + vy * t - y0) * uy
        if 0.0 <= along <= length:
            best = t
    for end in range(2):
        px = x0 if end == 0 else x1
        py = y0 if end == 0 else y1
        t = pair_time(x - px, y - py, vx, vy, reach)  # the disc seen from the end: the end closes at -v
        if t < best:
            best = t
            bx = px
            by = py
    return best, nx, ny, bx, by


@jit
def near_walls(x, y, radii, reach, walls):
    """Which dots start within ``reach`` px (beyond their radius) of a wall's bounding box: the others cannot
    touch a wall in a pass in which they move at most ``reach`` px (`WALL_MARGIN` included by the caller)."""
    near = np.zeros(x.size, np.bool_)
    for w in range(walls.shape[0]):
        x0 = min(walls[w, 0], walls[w, 2])
        x1 = max(walls[w, 0], walls[w, 2])
        y0 = min(walls[w, 1], walls[w, 3])
        y1 = max(walls[w, 1], walls[w, 3])
        for i in range(x.size):
            r = radii[i] + reach
            if x0 - r < x[i] < x1 + r and y0 - r < y[i] < y1 + r:
                near[i] = True
    return near


@jit(inline=True)
def schedule(i, now, s, buffer, start, partners, walls, near, event_time, event_with, event_count, event_end):
    """Find dot ``i``'s next event after ``now`` (its position is at ``now``): the earliest contact with a
    candidate neighbour (``partners[start[i]:start[i+1]]``; of equal times, the partner of lowest index) or,
    when it is ``near`` one, a wall. ``event_with`` gets the partner (>= 0), ``-1 - w`` for wall ``w``, or
    ``-(len(walls) + 1)`` for none; ``event_count`` the partner's collisions so far in the pass."""
    best = NEVER
    with_ = -(walls.shape[0] + 1)
    partner_count = 0.0
    xi = s[i, X]
    yi = s[i, Y]
    vxi = s[i, VX]
    vyi = s[i, VY]
    ri = s[i, RADIUS]
    for k in range(start[i], start[i + 1]):
        j = partners[k]
        lag = now - s[j, STAMP]
        dx = s[j, X] + s[j, VX] * lag - xi
        dy = s[j, Y] + s[j, VY] * lag - yi
        t = pair_time(dx, dy, s[j, VX] - vxi, s[j, VY] - vyi, ri + s[j, RADIUS] + 2.0 * buffer)
        if t < best:
            best = t
            with_ = j
            partner_count = s[j, COUNT]
    for w in range(walls.shape[0] if near[i] else 0):
        t, nx, ny, bx, by = wall_time(xi, yi, vxi, vyi, ri + buffer, walls[w, 0], walls[w, 1], walls[w, 2],
                                      walls[w, 3])
        if t < best:
            best = t
            with_ = -1 - w
            event_end[i, 0] = bx
            event_end[i, 1] = by
    event_time[i] = now + best
    event_with[i] = with_
    event_count[i] = partner_count


@jit(inline=True)
def move_to(i, t, s):
    lag = t - s[i, STAMP]
    s[i, X] += s[i, VX] * lag
    s[i, Y] += s[i, VY] * lag
    s[i, STAMP] = t


@jit
def collide_dots(a, b, s, record, words):
    """Eq 2.5 for dots ``a`` and ``b`` at contact: the normal velocities mix by a drawn restitution, the
    tangential ones stay."""
    dx = s[b, X] - s[a, X]
    dy = s[b, Y] - s[a, Y]
    d = math.sqrt(dx * dx + dy * dy)
    nx = dx / d
    ny = dy / d
    approach = -((s[b, VX] - s[a, VX]) * dx + (s[b, VY] - s[a, VY]) * dy) / d  # as `pair_time` measures it
    if approach <= RESTING:  # resting or parting (round-off at contact): nothing to resolve
        return
    eps = impact_elasticity(record, words, approach)
    ia = s[a, INV_MASS]
    ib = s[b, INV_MASS]
    share = (1.0 + eps) * approach / (ia + ib)
    s[a, VX] -= share * ia * nx
    s[a, VY] -= share * ia * ny
    s[b, VX] += share * ib * nx
    s[b, VY] += share * ib * ny


@jit
def collide_wall(i, nx, ny, bx, by, s, record, words):
    """Reflect dot ``i`` off a wall (its line's normal ``(nx, ny)``, or its end ``(bx, by)``) with the wall's
    restitution."""
    if not math.isnan(bx):
        nx = s[i, X] - bx
        ny = s[i, Y] - by
        d = math.sqrt(nx * nx + ny * ny)
        nx /= d
        ny /= d
    vn = s[i, VX] * nx + s[i, VY] * ny
    if vn >= 0.0:
        return
    words[DOT_WALL] += np.uint64(1)
    kick = (1.0 + record[WALL_ELASTICITY]) * vn
    s[i, VX] -= kick * nx
    s[i, VY] -= kick * ny


@jit
def pass_state(x, y, vx, vy, stamp, radii, inv_mass):
    """The dots' rows for a pass (`STATE_COLUMNS`), no collisions counted yet."""
    s = np.empty((x.size, STATE_COLUMNS))
    for k in range(x.size):
        s[k, X] = x[k]
        s[k, Y] = y[k]
        s[k, VX] = vx[k]
        s[k, VY] = vy[k]
        s[k, STAMP] = stamp[k]
        s[k, RADIUS] = radii[k]
        s[k, INV_MASS] = inv_mass[k]
        s[k, COUNT] = 0.0
    return s


@jit
def advance_events(x, y, vx, vy, stamp, now, end, radii, inv_mass, buffer, start, partners, walls, record,
                   speed_bound, max_events, events_done):
    """Resolve every event from ``now`` to ``end`` s in time order (the dots' positions at their ``stamp``).

    Returns ``(status, time, events)``: `DONE` (every dot moved to ``end``), `CAPPED` (``max_events`` reached
    counting ``events_done``; every dot moved to ``time``, the last event's) or `REBUILD` (a dot is now faster
    than ``speed_bound``; every dot moved to ``time`` for the caller to build the candidates again).
    """
    words = record.view(np.uint64)
    n = x.size
    s = pass_state(x, y, vx, vy, stamp, radii, inv_mass)
    event_time = np.empty(n)
    event_with = np.empty(n, np.int64)
    event_count = np.zeros(n)
    event_end = np.full((n, 2), math.nan)
    near = near_walls(x, y, radii, buffer + speed_bound * (end - now) + WALL_MARGIN, walls)
    calendar = new_calendar(n, now, end)
    for i in range(n):
        schedule(i, now, s, buffer, start, partners, walls, near, event_time, event_with, event_count, event_end)
        put(calendar, i, event_time[i], end)
    status = DONE
    events = events_done
    time = end
    bound2 = speed_bound * speed_bound
    while True:
        i = earliest(calendar, event_time)
        if i < 0:  # no event left within the frame
            break
        t = event_time[i]
        j = event_with[i]
        stale = j >= 0 and s[j, COUNT] != event_count[i]
        fast = False
        if stale:  # the partner collided since: predict again from now
            move_to(i, now, s)  # its own path did not change: moving it is exact
            j = -1
        else:
            if events >= max_events:
                status = CAPPED
                time = now
                break
            events += 1
            now = t
            move_to(i, t, s)
            s[i, COUNT] += 1.0
            if j >= 0:
                move_to(j, t, s)
                s[j, COUNT] += 1.0
                collide_dots(i, j, s, record, words)
            else:
                w = -1 - j
                ex = event_end[i, 0]
                ey = event_end[i, 1]
                nx = 0.0
                ny = 0.0
                if math.isnan(ex):
                    t_, nx, ny, ex, ey = wall_time(s[i, X], s[i, Y], 0.0, 0.0, s[i, RADIUS] + buffer, walls[w, 0],
                                                  walls[w, 1], walls[w, 2], walls[w, 3])
                collide_wall(i, nx, ny, ex, ey, s, record, words)
            event_end[i, 0] = math.nan
            event_end[i, 1] = math.nan
            fast = s[i, VX] * s[i, VX] + s[i, VY] * s[i, VY] > bound2
            if j >= 0:
                fast = fast or s[j, VX] * s[j, VX] + s[j, VY] * s[j, VY] > bound2
                event_end[j, 0] = math.nan
                event_end[j, 1] = math.nan
        for k in (i, j):  # their next events, from now (one call site: the search is inlined here)
            if k >= 0:
                schedule(k, now, s, buffer, start, partners, walls, near, event_time, event_with, event_count,
                         event_end)
                put(calendar, k, event_time[k], end)
        if fast:
            status = REBUILD
            time = now
            break
    for k in range(n):
        move_to(k, time, s)
        x[k] = s[k, X]
        y[k] = s[k, Y]
        vx[k] = s[k, VX]
        vy[k] = s[k, VY]
        stamp[k] = s[k, STAMP]
    return status, time, events


@jit
def neighbour_table(n, i, j):
    """Each dot's candidate neighbours from the pairs ``(i[k], j[k])``: ``(start, partners)``, dot ``a``'s being
    ``partners[start[a]:start[a + 1]]``."""
    degree = np.zeros(n + 1, np.int64)
    for k in range(i.size):
        degree[i[k] + 1] += 1
        degree[j[k] + 1] += 1
    start = np.cumsum(degree)
    fill = start[:-1].copy()
    partners = np.empty(2 * i.size, np.int64)
    for k in range(i.size):
        partners[fill[i[k]]] = j[k]
        fill[i[k]] += 1
        partners[fill[j[k]]] = i[k]
        fill[j[k]] += 1
    return start, partners


@jit
def fastest(vx, vy):
    """The largest speed, px/s."""
    top = 0.0
    for k in range(vx.size):
        top = max(top, vx[k] * vx[k] + vy[k] * vy[k])
    return math.sqrt(top)
