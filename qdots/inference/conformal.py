"""Honest interval widths for ``qdots infer``: split-conformal calibration of the posterior's central intervals.

A neural posterior trained on a thousand films is overconfident for the parameters the films hardly tell
(measured: the raw 90 % intervals of the mass exponent and the drag held the truth in 68-79 % of held-out
films). Averaging more networks did not help. So a share of the library's films (`CALIBRATION_SHARE`,
chosen by a hash of each film's id, so a growing library keeps its choice) is kept out of the training.
On each of those films, whose parameters are known, the posterior gives a median ``m`` and a central
interval ``[lo, hi]`` per parameter. The film's score is how far the interval must be spread about its
median to reach the truth ``t``:

    score = (t - m) / (hi - m)   if t >= m,   else   (m - t) / (m - lo).

The factor is the ``ceil((n + 1) level) / n`` empirical quantile of the ``n`` films' scores (split conformal
prediction: Vovk et al. 2005; Angelopoulos & Bates 2021, "A gentle introduction to conformal prediction").
For a film drawn as the library's films are, the spread interval ``[m - f (m - lo), m + f (hi - m)]`` then
holds the truth with probability at least ``level``, whatever the network got wrong. The guarantee is
marginal (on average over the prior's films), not film by film. A factor below 1 narrows an underconfident
interval. The draws are spread about their medians by the same factor and clipped to the prior's box, so
their percentiles are the calibrated interval; clipping never drops the truth, which lies inside the box.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass

import numpy as np

#: Share of a library's films kept out of the training to calibrate the intervals, and the fewest such films
#: a factor is fitted from (fewer leave the factor infinite: every interval is the prior's box).
CALIBRATION_SHARE, MIN_CALIBRATION_FILMS = 0.2, 20


def is_calibration_film(film_id: str, share: float = CALIBRATION_SHARE) -> bool:
    """Whether the film ``film_id`` is kept for calibration: a fixed function of the id (its SHA-256)."""
    digest = int(hashlib.sha256(str(film_id).encode()).hexdigest()[:8], 16)
    return digest < share * 16**8


def central_quantiles(samples: np.ndarray, level: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per column of ``samples`` (n, k): the lower end, the median and the upper end of the central ``level``
    interval."""
    tail = 50.0 * (1.0 - level)
    low, median, high = np.percentile(samples, [tail, 50.0, 100.0 - tail], axis=0)
    return low, median, high


def conformal_scores(truth: np.ndarray, low: np.ndarray, median: np.ndarray, high: np.ndarray) -> np.ndarray:
    """The factor by which each interval (rows: films, columns: parameters) must be spread about its median to
    reach the truth (see the module). An interval of zero width on the truth's side scores infinity unless the
    truth is its median."""
    above = truth >= median
    reach = np.where(above, high - median, median - low)
    distance = np.abs(truth - median)
    with np.errstate(divide="ignore", invalid="ignore"):
        scores = np.where(reach > 0, distance / np.where(reach > 0, reach, 1.0), np.where(distance > 0, np.inf, 0.0))
    return scores


def conformal_factor(scores: np.ndarray, level: float) -> np.ndarray:
    """Per column of ``scores`` (films, parameters): the split-conformal quantile, ``ceil((n + 1) level)``-th
    smallest of n scores; infinite when n is below `MIN_CALIBRATION_FILMS` or too small for ``level``."""
    scores = np.asarray(scores, dtype=float).reshape(len(scores), -1)
    n = len(scores)
    rank = math.ceil((n + 1) * level)
    if n < MIN_CALIBRATION_FILMS or rank > n:
        return np.full(scores.shape[1], np.inf)
    return np.sort(scores, axis=0)[rank - 1]


def spread_draws(samples: np.ndarray, factors: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """``samples`` (n, k) spread about each column's median by ``factors`` and clipped to the box [low, high]
    (an infinite factor sends every draw off its median to the box's bound on its side)."""
    median = np.median(samples, axis=0)
    offset = samples - median
    with np.errstate(invalid="ignore"):
        spread = median + np.where(offset == 0, 0.0, np.asarray(factors, dtype=float) * offset)
    return np.clip(spread, low, high)


def describe_factor(factor: float) -> str:
    """A factor in words: ``"x1.16"``, or, when infinite, that the interval is the prior's."""
    if math.isfinite(factor):
        return f"x{factor:.2f}"
    return f"none fitted (under {MIN_CALIBRATION_FILMS} calibration films): the prior's bounds"


@dataclass(frozen=True)
class IntervalCalibration:
    """What the calibration films gave.

    Attributes
    ----------
    level : float
        Credible level the factors are fitted for.
    factors : ndarray (k,)
        Per parameter, the spread applied to the posterior's draws about their median.
    films : int
        Calibration films the factors come from.
    """

    level: float
    factors: np.ndarray
    films: int

    def apply(self, samples: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
        """The draws `spread_draws` makes of ``samples`` in the box [low, high]."""
        return spread_draws(samples, self.factors, low, high)


def fit_calibration(truth: np.ndarray, draws: list[np.ndarray], level: float) -> IntervalCalibration:
    """The factors from calibration films: ``truth`` (films, k) and each film's posterior draws (n, k)."""
    truth = np.asarray(truth, dtype=float)
    if not draws:
        k = truth.shape[-1] if truth.ndim == 2 else 0
        return IntervalCalibration(level, np.full(k, np.inf), 0)
    truth = truth.reshape(len(draws), -1)
    bounds = np.array([central_quantiles(d, level) for d in draws])  # (films, 3, k)
    scores = conformal_scores(truth, bounds[:, 0], bounds[:, 1], bounds[:, 2])
    return IntervalCalibration(level, conformal_factor(scores, level), len(draws))
