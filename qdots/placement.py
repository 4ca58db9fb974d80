"""Initial placement of dots on the board (thesis deposition, section 2.3).

`random_sequential` is random sequential addition (RSA): dots are placed one
at a time at uniformly random positions, and a candidate that overlaps a dot
already placed is rejected and drawn again, diameter and position both, as
the thesis's deposition code does (Appendix A, ``addRandomBallInRect``).

Candidates are drawn in fixed-size batches and tested against the placed
dots with a KD-tree in one vectorized query (`qdots.geometry.DiscTree`); the
survivors of a batch are then accepted in draw order, each only if it clears
the ones accepted before it (`qdots.geometry.clashing_pairs`). This
consumes the candidate stream exactly as a one-at-a-time loop would, so the
result is the sequential process, and since the batch size is fixed, the
first ``k`` dots placed for ``n`` dots are the ``k`` dots placed for any
other ``n >= k`` with the same seed.
"""

from __future__ import annotations

import math

import numpy as np

from labrig.validate import InputError, choice, count, generator, real, reals

from .geometry import DiscTree, clashing_pairs
from .scene import MAX_DOTS, MAX_LENGTH, MIN_DIAMETER

#: Candidates drawn per batch. Part of the random stream: changing it changes the placements.
BATCH = 256
#: Most consecutive rejected candidates for one dot.
MAX_TRIES = 10_000_000
#: Most candidates of one `draw_candidates` call (the batches here hold 256, a deposition's 32).
MAX_CANDIDATES = 1_000_000


def _check_args(n, box, mean_diameter, sigma, max_tries, margin) -> tuple[float, float]:
    count("n", n, 0, MAX_DOTS)
    w, h = reals("box", box, 2, 0.0, MAX_LENGTH, unit="px")
    if not (w > 0 and h > 0):
        raise InputError(f"box must be two sizes > 0 px, got {box!r}")
    real("mean_diameter", mean_diameter, MIN_DIAMETER, MAX_LENGTH, unit="px")
    real("sigma", sigma, 0.0, 1.0, high_open=True)
    count("max_tries", max_tries, 1, MAX_TRIES)
    real("margin", margin, 0.0, MAX_LENGTH, unit="px")
    if n > 0 and mean_diameter + 2.0 * margin > min(w, h):
        raise InputError(
            f"mean_diameter {mean_diameter:g} px (+ 2 x margin {margin:g} px) does not fit in the "
            f"box {w:g} x {h:g} px"
        )
    return w, h


def draw_candidates(rng: np.random.Generator, m: int, region: tuple[float, float, float, float],
                    mean_diameter: float, sigma: float, margin: float = 0.0):
    """Draw ``m`` candidate dots for rejection placement: diameters, then centres.

    Diameters are ``mean_diameter (1 + sigma N(0, 1))`` (no random draw when
    ``sigma == 0``); centres are uniform over the positions where the dot,
    grown by ``margin``, lies inside ``region = (x0, y0, x1, y1)`` px.

    ``m`` is in [0, `MAX_CANDIDATES`].

    Returns
    -------
    centres : ndarray, shape (m, 2)
    radii : ndarray, shape (m,)
    fits : ndarray of bool, shape (m,)
        False for a non-positive diameter or a dot too big for the region
        (such candidates must be rejected, which redraws both).
    """
    count("m", m, 0, MAX_CANDIDATES)
    x0, y0, x1, y1 = region
    d = mean_diameter * (1.0 + sigma * rng.standard_normal(m)) if sigma > 0 else np.full(m, mean_diameter)
    u = rng.random((m, 2))
    r = 0.5 * d
    keep_out = r + margin
    # Round-off insurance: the centre range is shrunk by a few ulps of the region so that
    # x - r >= x0 and x + r <= x1 hold exactly after floating-point evaluation.
    slack = 8.0 * np.finfo(float).eps * max(abs(x0), abs(x1), abs(y0), abs(y1), 1.0)
    span_x = (x1 - x0) - 2.0 * keep_out - 2.0 * slack
    span_y = (y1 - y0) - 2.0 * keep_out - 2.0 * slack
    fits = (d > 0) & (span_x >= 0) & (span_y >= 0)
    x = x0 + keep_out + slack + u[:, 0] * np.maximum(span_x, 0.0)
    y = y0 + keep_out + slack + u[:, 1] * np.maximum(span_y, 0.0)
    return np.column_stack([x, y]), r, fits


def _accept_in_order(pos, r, margin) -> np.ndarray:
    """Greedy acceptance in draw order among candidates that clear the placed dots.

    Returns a boolean mask: candidate ``b`` is accepted unless it clashes with
    an accepted candidate ``a < b``. Only clashing pairs are visited.
    """
    accepted = np.ones(len(r), dtype=bool)
    a, b = clashing_pairs(pos, r, margin)  # a < b
    order = np.lexsort((a, b))  # by b, then a: a's fate is settled before any b > a is decided
    for ai, bi in zip(a[order].tolist(), b[order].tolist()):
        if accepted[ai]:
            accepted[bi] = False
    return accepted


def random_sequential(
    n: int,
    box: tuple[float, float],
    mean_diameter: float = 15.0,
    sigma: float = 0.0,
    rng: np.random.Generator | int | None = None,
    max_tries: int = 10_000,
    margin: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Place ``n`` non-overlapping dots by random sequential addition.

    Each dot's diameter is drawn as ``d = mean_diameter * (1 + sigma * N(0, 1))``
    and its centre uniformly among the positions where the dot lies fully
    inside the box. A candidate that overlaps a dot already placed, or has a
    non-positive diameter, or is too large to fit in the box, is rejected and
    both diameter and position are drawn again.

    Parameters
    ----------
    n : int
        Number of dots (>= 0).
    box : (float, float)
        Board width and height, px. The board spans ``[0, w] x [0, h]``.
    mean_diameter : float
        Mean dot diameter, px (> 0). Thesis: 15 px.
    sigma : float
        Standard deviation of the diameter as a fraction of the mean, in
        [0, 1). Thesis: 0, 0.05, 0.10, 0.15.
    rng : numpy.random.Generator, int or None
        Source of randomness, or a seed for one. Equal seeds give equal boards.
    max_tries : int
        Consecutive rejected candidates for one dot after which the board is
        declared too full (>= 1).
    margin : float
        Smallest clearance kept between two dot surfaces and between a dot and
        the box edges, px (>= 0). The thesis's code keeps a tiny gap
        (``epsilonSpace``); 0 accepts exact contact.

    Returns
    -------
    positions : ndarray, shape (n, 2)
        Dot centres, px, in placement order.
    radii : ndarray, shape (n,)
        Dot radii, px.

    Raises
    ------
    ValueError
        On a bad argument (the message names it), or when ``max_tries``
        consecutive candidates fail for one dot (the board is too full; the
        message gives how many dots were placed and the area fraction).

    Notes
    -----
    RSA of equal discs jams at an area fraction of about 0.547, far below
    hexagonal close packing (0.907); denser boards need compression (e.g.
    `qdots.CentreGravity`) after placement.
    """
    w, h = _check_args(n, box, mean_diameter, sigma, max_tries, margin)
    gen = generator("rng", rng)
    n = int(n)
    positions = np.empty((n, 2))
    radii = np.empty(n)
    k = 0  # dots placed
    failures = 0  # consecutive rejected candidates for dot k
    placed = DiscTree(positions[:0], radii[:0])  # the dots placed; rebuilt when a batch added dots
    while k < n:
        pos, r, ok = draw_candidates(gen, BATCH, (0.0, 0.0, w, h), float(mean_diameter), float(sigma), float(margin))
        ok &= placed.clashing_partners(pos, r, margin) < 0
        survivors = np.flatnonzero(ok)
        accepted = survivors[_accept_in_order(pos[survivors], r[survivors], margin)][: n - k]
        # Consecutive failures before each accepted candidate, in draw order.
        gaps = np.diff(accepted, prepend=-1) - 1
        if len(gaps):
            gaps[0] += failures
        too_many = np.flatnonzero(gaps >= max_tries)
        if too_many.size:
            _too_full(n, k + int(too_many[0]), (w, h), mean_diameter, sigma, max_tries,
                      np.concatenate([radii[:k], r[accepted[: too_many[0]]]]))
        failures = (BATCH - 1 - int(accepted[-1])) if len(accepted) else failures + BATCH
        positions[k : k + len(accepted)] = pos[accepted]
        radii[k : k + len(accepted)] = r[accepted]
        k += len(accepted)
        if k < n and failures >= max_tries:
            _too_full(n, k, (w, h), mean_diameter, sigma, max_tries, radii[:k])
        if len(accepted):
            placed = DiscTree(positions[:k], radii[:k])
    return positions, radii


def _too_full(n, placed, box, mean_diameter, sigma, max_tries, placed_radii) -> None:
    w, h = box
    area = w * h
    fraction = float(np.sum(np.pi * placed_radii**2)) / area
    wanted = n * np.pi * (mean_diameter / 2.0) ** 2 * (1.0 + sigma**2) / area
    raise InputError(
        f"board too full: placed {placed} of {n} dots (mean diameter {mean_diameter:g} px, "
        f"sigma {sigma:g}) in a {w:g} x {h:g} px box before {max_tries} consecutive tries failed; "
        f"area fraction reached {fraction:.3f} of {wanted:.3f} requested (random sequential "
        f"placement jams near 0.55)"
    )


#: Layouts of `hexagonal_lattice`.
LATTICE_LAYOUTS = ("rectangle", "parallelogram", "flake")
#: Largest ``m`` of `hexagonal_lattice` by layout: at most `qdots.scene.MAX_DOTS` points (``m * m``, and
#: ``3 m (m + 1) + 1`` for a flake: 997,057 at 576 rings; the benchmark's flake has 182).
MAX_LATTICE_SIZE = {"rectangle": 1000, "parallelogram": 1000, "flake": 576}


def hexagonal_lattice(m: int, pitch: float, layout: str = "rectangle", origin=(0.0, 0.0)) -> np.ndarray:
    """Centres of a patch of the hexagonal (triangular) lattice: close-packed dots of diameter ``pitch`` touch.

    Parameters
    ----------
    m : int
        Size: points per side (``"rectangle"``, ``"parallelogram"``: ``m * m`` points), or rings around
        the centre point (``"flake"``: ``3 m (m + 1) + 1`` points, the centre at ``origin``); at most
        `MAX_LATTICE_SIZE` of the layout (`qdots.scene.MAX_DOTS` points).
    pitch : float
        Nearest-neighbour distance, px (> 0).
    layout : {"rectangle", "parallelogram", "flake"}
        ``"rectangle"``: point ``(i, j)`` at ``pitch (i + (j mod 2) / 2, sqrt(3)/2 j)`` (every other row
        shifted); ``"parallelogram"``: at ``pitch (i + j / 2, sqrt(3)/2 j)``; ``"flake"``: the points of
        the parallelogram with ``|i|, |j|, |i + j| <= m``, a hexagon.
    origin : (float, float)
        Added to every point, px.

    Returns
    -------
    ndarray, shape (N, 2)
        In the order of ``i`` then ``j`` (C order of the ``(i, j)`` grid).
    """
    choice("layout", layout, LATTICE_LAYOUTS)
    m = count("m", m, 0, MAX_LATTICE_SIZE[layout])
    pitch = real("pitch", pitch, 0.0, MAX_LENGTH, low_open=True, unit="px")
    low = -m if layout == "flake" else 0
    high = m + 1 if layout == "flake" else m
    i, j = (a.ravel() for a in np.meshgrid(np.arange(low, high), np.arange(low, high), indexing="ij"))
    if layout == "flake":
        keep = np.abs(i + j) <= m
        i, j = i[keep], j[keep]
    shift = 0.5 * (j % 2) if layout == "rectangle" else 0.5 * j
    x = pitch * (i + shift)
    y = pitch * math.sqrt(3) / 2 * j
    return np.column_stack([x, y]) + np.asarray(reals("origin", origin, 2))
