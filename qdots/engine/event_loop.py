"""The thesis's event-driven hard discs, compiled: every collision of a frame found and resolved exactly, in
time order (section 2.2, steps 4-11).

Within a frame the dots move in straight lines (the forces changed their velocities at the frame's start,
steps 1-3). Each dot has a next event: the earliest contact with a candidate neighbour or a wall, its
discs widened by the buffer (the thesis adds a millionth of the mean radius to every radius, so dots
resolved at contact stay that far apart and round-off never makes them overlap). The earliest event of
all (a tournament tree over the dots) is resolved: the two discs are moved to its time (each dot keeps
its own time stamp; the others move only when needed, which is exact in straight lines, where the thesis
moved every dot to each collision), their velocities change by Eq 2.5 (`impact_elasticity`) or by the
wall's restitution, and their next events are found again. A dot whose scheduled partner has collided
since is rescheduled when its stale event comes up (its own path did not change, so nothing earlier can
have been missed). The frame ends when the next event lies beyond it, or after ``max_events`` events
(the thesis's cap: the rest of the frame is then not moved, as its loop did); every dot is then moved to
the frame's end.

Candidate neighbours are the pairs that can touch within the frame at the speeds they may reach
(`candidate_reach`); a collision that makes some dot faster than that bound ends the pass early and the
caller builds the candidates again from that moment, so no contact is missed.
"""

from __future__ import annotations

import math

import numpy as np

from labrig.compiled import jit

from .contacts import DOT_WALL, RESTING, WALL_ELASTICITY, impact_elasticity

#: Why `advance_events` returned: the frame is done, the event cap was reached, or a dot got faster than
#: the candidates were built for (the caller rebuilds them and goes on).
DONE, CAPPED, REBUILD = 0, 1, 2
#: No event.
NEVER = math.inf




@jit(inline=True)
def pair_time(dx, dy, dvx, dvy, sigma):
    """Time until two discs whose centres are ``(dx, dy)`` apart (px, from the first to the second) and close
    at ``(dvx, dvy)`` (px/s, the second's velocity less the first's) come within ``sigma`` px; 0 when they are
    already that close and approaching, inf when they never do (or close more slowly than
    `qdots.engine.contacts.RESTING`: within a frame they would close by far less than the buffer)."""
    b = dx * dvx + dy * dvy
    if b >= -RESTING * math.sqrt(dx * dx + dy * dy):
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
def build_tree(times, tree):
    """A tournament tree over ``times``: ``tree[k]`` is the index of the earliest among the leaves below node k
    (leaves at ``size + i``; ``tree`` has ``2 size`` slots, ``size`` a power of two >= len(times))."""
    size = tree.size // 2
    for i in range(size):
        tree[size + i] = i
    for k in range(size - 1, 0, -1):
        tree[k] = earlier(times, tree[2 * k], tree[2 * k + 1])


@jit(inline=True)
def earlier(times, a, b):
    n = times.size
    if b >= n:
        return a
    if a >= n:
        return b
    return a if times[a] <= times[b] else b


@jit(inline=True)
def update_tree(times, tree, i):
    """Re-rank leaf ``i`` after its time changed."""
    k = (tree.size // 2 + i) // 2
    while k >= 1:
        tree[k] = earlier(times, tree[2 * k], tree[2 * k + 1])
        k //= 2


@jit
def schedule(i, now, x, y, vx, vy, stamp, radii, buffer, start, partners, walls, counts, event_time, event_with,
             event_count, event_end):
    """Find dot ``i``'s next event after ``now`` (its position is at ``now``): the earliest contact with a
    candidate neighbour (``partners[start[i]:start[i+1]]``) or a wall. ``event_with`` gets the partner (>= 0),
    ``-1 - w`` for wall ``w``, or ``-(len(walls) + 1)`` for none; ``event_count`` the partner's collision count."""
    best = NEVER
    with_ = -(walls.shape[0] + 1)
    partner_count = 0
    for k in range(start[i], start[i + 1]):
        j = partners[k]
        lag = now - stamp[j]
        dx = x[j] + vx[j] * lag - x[i]
        dy = y[j] + vy[j] * lag - y[i]
        t = pair_time(dx, dy, vx[j] - vx[i], vy[j] - vy[i], radii[i] + radii[j] + 2.0 * buffer)
        if t < best:
            best = t
            with_ = j
            partner_count = counts[j]
    for w in range(walls.shape[0]):
        t, nx, ny, bx, by = wall_time(x[i], y[i], vx[i], vy[i], radii[i] + buffer, walls[w, 0], walls[w, 1],
                                      walls[w, 2], walls[w, 3])
        if t < best:
            best = t
            with_ = -1 - w
            event_end[i, 0] = bx
            event_end[i, 1] = by
    event_time[i] = now + best
    event_with[i] = with_
    event_count[i] = partner_count


@jit(inline=True)
def move_to(i, t, x, y, vx, vy, stamp):
    lag = t - stamp[i]
    x[i] += vx[i] * lag
    y[i] += vy[i] * lag
    stamp[i] = t


@jit
def collide_dots(a, b, x, y, vx, vy, inv_mass, record, words):
    """Eq 2.5 for dots ``a`` and ``b`` at contact: the normal velocities mix by a drawn restitution, the
    tangential ones stay."""
    dx = x[b] - x[a]
    dy = y[b] - y[a]
    d = math.sqrt(dx * dx + dy * dy)
    nx = dx / d
    ny = dy / d
    approach = -((vx[b] - vx[a]) * dx + (vy[b] - vy[a]) * dy) / d  # as `pair_time` measures it
    if approach <= RESTING:  # resting or parting (round-off at contact): nothing to resolve
        return
    eps = impact_elasticity(record, words, approach)
    share = (1.0 + eps) * approach / (inv_mass[a] + inv_mass[b])
    vx[a] -= share * inv_mass[a] * nx
    vy[a] -= share * inv_mass[a] * ny
    vx[b] += share * inv_mass[b] * nx
    vy[b] += share * inv_mass[b] * ny


@jit
def collide_wall(i, nx, ny, bx, by, x, y, vx, vy, record, words):
    """Reflect dot ``i`` off a wall (its line's normal ``(nx, ny)``, or its end ``(bx, by)``) with the wall's
    restitution."""
    if not math.isnan(bx):
        nx = x[i] - bx
        ny = y[i] - by
        d = math.sqrt(nx * nx + ny * ny)
        nx /= d
        ny /= d
    vn = vx[i] * nx + vy[i] * ny
    if vn >= 0.0:
        return
    words[DOT_WALL] += np.uint64(1)
    kick = (1.0 + record[WALL_ELASTICITY]) * vn
    vx[i] -= kick * nx
    vy[i] -= kick * ny


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
    counts = np.zeros(n, np.int64)
    event_time = np.empty(n)
    event_with = np.empty(n, np.int64)
    event_count = np.zeros(n, np.int64)
    event_end = np.full((n, 2), math.nan)
    for i in range(n):
        schedule(i, now, x, y, vx, vy, stamp, radii, buffer, start, partners, walls, counts, event_time, event_with,
                 event_count, event_end)
    size = 1
    while size < max(n, 1):
        size *= 2
    tree = np.zeros(2 * size, np.int64)
    build_tree(event_time, tree)
    status = DONE
    events = events_done
    time = end
    bound2 = speed_bound * speed_bound
    while n:
        i = tree[1]
        t = event_time[i]
        if not t <= end:  # the next event lies beyond the frame (or there is none)
            break
        j = event_with[i]
        if j >= 0 and counts[j] != event_count[i]:  # the partner collided since: predict again from now
            move_to(i, now, x, y, vx, vy, stamp)  # its own path did not change: moving it is exact
            schedule(i, now, x, y, vx, vy, stamp, radii, buffer, start, partners, walls, counts, event_time,
                     event_with, event_count, event_end)
            update_tree(event_time, tree, i)
            continue
        if events >= max_events:
            status = CAPPED
            time = now
            break
        events += 1
        now = t
        move_to(i, t, x, y, vx, vy, stamp)
        counts[i] += 1
        if j >= 0:
            move_to(j, t, x, y, vx, vy, stamp)
            counts[j] += 1
            collide_dots(i, j, x, y, vx, vy, inv_mass, record, words)
        else:
            w = -1 - j
            ex = event_end[i, 0]
            ey = event_end[i, 1]
            nx = 0.0
            ny = 0.0
            if math.isnan(ex):
                t_, nx, ny, ex, ey = wall_time(x[i], y[i], 0.0, 0.0, radii[i] + buffer, walls[w, 0], walls[w, 1],
                                              walls[w, 2], walls[w, 3])
            collide_wall(i, nx, ny, ex, ey, x, y, vx, vy, record, words)
        event_end[i, 0] = math.nan
        event_end[i, 1] = math.nan
        fast = vx[i] * vx[i] + vy[i] * vy[i] > bound2
        schedule(i, t, x, y, vx, vy, stamp, radii, buffer, start, partners, walls, counts, event_time, event_with,
                 event_count, event_end)
        update_tree(event_time, tree, i)
        if j >= 0:
            fast = fast or vx[j] * vx[j] + vy[j] * vy[j] > bound2
            event_end[j, 0] = math.nan
            event_end[j, 1] = math.nan
            schedule(j, t, x, y, vx, vy, stamp, radii, buffer, start, partners, walls, counts, event_time,
                     event_with, event_count, event_end)
            update_tree(event_time, tree, j)
        if fast:
            status = REBUILD
            time = t
            break
    for k in range(n):
        move_to(k, time, x, y, vx, vy, stamp)
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
