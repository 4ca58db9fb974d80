"""The continuum limit of the thesis's rule as a flow of the metal surface (compiled with numba).

At oxide thickness ``t`` every metal point is at distance ``t`` from the oxide (the thesis's
algorithm always oxidizes the metal point closest to the oxide), and the oxide that a patch of
metal makes grows above it, at its nearest oxide point. The horizontal area of oxide fed by a metal
patch is ``J`` times the patch's own, ``J = (1 + t k1)(1 + t k2)`` with ``k1``, ``k2`` the metal's
principal curvatures (positive where it bulges up), so the volume balance at each point gives the
metal's normal recession speed per unit of thickness:

    V = J / (J + k_exp - 1),        1 / k_exp on a flat film,

and the oxide above moves out at ``1 - V``. Where ``1 + t k2 <= 0`` (a valley narrower than the
oxide is thick) the metal below a crease of the oxide is a circular arc of radius ``t``, fed by no
oxide point of its own: ``J = 0`` and it stops (docs/planarize_continuum.md derives all of this).

The ``"conformal"`` rule (`planarize.model.RULES`) moves the whole metal at one speed, the same
expression with ``J`` replaced by its area mean, the oxide's area over the metal's (`surface_area` of
each surface): the volume balances over the whole surface instead of at each point.

The metal is a height field ``M`` on a grid; its normal speed ``V`` moves it down by
``V sqrt(1 + |grad M|^2)`` per unit of thickness. Slopes are upwind (Godunov's flux for a surface
moving down, second-order ENO differences), curvatures central; time integration is Heun's method.
Boundaries: periodic, or open, where the surface is mirrored about its edge points.
"""

from __future__ import annotations

import math

import numpy as np

from labrig.compiled import jit

#: Ghost points on each side of the padded grid (the ENO slopes reach two points).
GHOST = 2


@jit
def fill_ghosts(p: np.ndarray, periodic: bool) -> None:
    """Fill the ``GHOST`` layers of the padded array ``p`` from its interior: periodic images, or the
    mirror image about the edge points (``z[-1] = z[1]``) of an open grid."""
    g = GHOST
    nx = p.shape[0] - 2 * g
    ny = p.shape[1] - 2 * g
    for i in range(g, g + nx):
        for s in range(1, g + 1):
            if periodic:
                p[i, g - s] = p[i, g + ny - s]
                p[i, g + ny - 1 + s] = p[i, g - 1 + s]
            else:
                p[i, g - s] = p[i, g + min(s, ny - 1)]
                p[i, g + ny - 1 + s] = p[i, g + ny - 1 - min(s, ny - 1)]
    for s in range(1, g + 1):
        for j in range(p.shape[1]):
            if periodic:
                p[g - s, j] = p[g + nx - s, j]
                p[g + nx - 1 + s, j] = p[g - 1 + s, j]
            else:
                p[g - s, j] = p[g + min(s, nx - 1), j]
                p[g + nx - 1 + s, j] = p[g + nx - 1 - min(s, nx - 1), j]


@jit(inline=True)
def _minmod(a, b):
    return a if abs(a) < abs(b) else b


@jit(inline=True)
def _down_slope2(m2, m1, c, p1, p2, rh):
    """Squared upwind slope along one axis for a surface moving down (Godunov, ENO2; ``rh`` = 1 / spacing)."""
    curve = p1 - 2.0 * c + m1
    dm = (c - m1 + 0.5 * _minmod(c - 2.0 * m1 + m2, curve)) * rh
    dp = (p1 - c - 0.5 * _minmod(curve, p2 - 2.0 * p1 + c)) * rh
    return max(dm, 0.0) ** 2 + min(dp, 0.0) ** 2


@jit(inline=True)
def curvatures(p, i, j, rdx, rdy):
    """The principal curvatures (k1 >= k2, positive where the surface bulges up) and ``1 + |grad z|^2``
    at padded point (i, j), from central differences (``rdx``, ``rdy``: the inverse spacings)."""
    c = p[i, j]
    xm = p[i - 1, j]
    xp = p[i + 1, j]
    ym = p[i, j - 1]
    yp = p[i, j + 1]
    zx = 0.5 * (xp - xm) * rdx
    zy = 0.5 * (yp - ym) * rdy
    zxx = (xp - 2.0 * c + xm) * rdx * rdx
    zyy = (yp - 2.0 * c + ym) * rdy * rdy
    zxy = 0.25 * (p[i + 1, j + 1] - p[i + 1, j - 1] - p[i - 1, j + 1] + p[i - 1, j - 1]) * rdx * rdy
    g = 1.0 + zx * zx + zy * zy
    mean = -((1.0 + zy * zy) * zxx - 2.0 * zx * zy * zxy + (1.0 + zx * zx) * zyy) / (2.0 * g * math.sqrt(g))
    gauss = (zxx * zyy - zxy * zxy) / (g * g)
    disc = math.sqrt(max(mean * mean - gauss, 0.0))
    return mean + disc, mean - disc, g


@jit(inline=True)
def area_ratio(k1, k2, t):
    """``J = (1 + t k1)(1 + t k2)``, the oxide's horizontal area per metal area above a point, and 0
    where the metal lies below a crease of the oxide (``1 + t k2 <= 0``)."""
    low = 1.0 + t * k2
    if low <= 0.0:
        return 0.0
    return (1.0 + t * k1) * low


@jit
def metal_rate(p, dx, dy, t, k_exp, uniform_speed, rate, row_stiff, start, stop):
    """The metal's rate of change per unit of thickness, ``dM/dt``, at the interior points of rows
    [start, stop) of the padded heights ``p`` (ghosts filled), into ``rate`` (nx, ny).

    ``uniform_speed`` < 0 selects the thesis's rule (each point's own ``J``); otherwise it is the
    ``"conformal"`` rule's one speed. ``row_stiff[i]`` receives the row's largest diffusion coefficient
    of the linearized flow, nm (for the explicit time step).
    """
    g = GHOST
    ny = rate.shape[1]
    rdx = 1.0 / dx
    rdy = 1.0 / dy
    for i in range(start, stop):
        stiff = 0.0
        for j in range(ny):
            pi, pj = i + g, j + g
            k1, k2, grad2 = curvatures(p, pi, pj, rdx, rdy)
            if uniform_speed < 0.0:
                jac = area_ratio(k1, k2, t)
                total = jac + k_exp - 1.0
                if total > 0.0:
                    speed = jac / total
                    # dV/dk = (k_exp - 1) t (1 + t k_other) / (J + k_exp - 1)^2, per unit of curvature
                    d = (k_exp - 1.0) * t * max(1.0 + t * k1, 0.0) / (total * total * grad2)
                    stiff = max(stiff, d)
                else:  # no expansion (k_exp = 1) below a crease of the oxide: the metal stays, as for k_exp > 1
                    speed = 0.0
            else:
                speed = uniform_speed
            c = p[pi, pj]
            sx = _down_slope2(p[pi - 2, pj], p[pi - 1, pj], c, p[pi + 1, pj], p[pi + 2, pj], rdx)
            sy = _down_slope2(p[pi, pj - 2], p[pi, pj - 1], c, p[pi, pj + 1], p[pi, pj + 2], rdy)
            rate[i, j] = -speed * math.sqrt(1.0 + sx + sy)
        row_stiff[i] = stiff


def surface_area(z: np.ndarray, dx: float, dy: float, periodic: bool, weights: np.ndarray) -> float:
    """The area of the height field ``z``, nm^2: each point's horizontal share (``weights``,
    `planarize.heightfield.volume_weights`) times ``sqrt(1 + |grad z|^2)``, with central differences
    (one-sided at open edges). The ``"conformal"`` rule balances the oxide's and the metal's areas."""
    if periodic:
        gx = (np.roll(z, -1, axis=0) - np.roll(z, 1, axis=0)) / (2.0 * dx)
        gy = (np.roll(z, -1, axis=1) - np.roll(z, 1, axis=1)) / (2.0 * dy)
    else:
        gx, gy = np.gradient(z, dx, dy)
    return float(np.sum(weights * np.sqrt(1.0 + gx * gx + gy * gy)))
