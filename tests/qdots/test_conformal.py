"""The split-conformal calibration of ``qdots infer``'s intervals (`qdots.inference.conformal`), on toy posteriors
whose miscalibration is known: pure numpy, no network."""

from __future__ import annotations

import numpy as np
import pytest

from qdots.inference.conformal import (
    CALIBRATION_SHARE,
    MIN_CALIBRATION_FILMS,
    central_quantiles,
    conformal_factor,
    conformal_scores,
    fit_calibration,
    is_calibration_film,
    spread_draws,
)


def toy_films(rng, films: int, width: float, draws: int = 400):
    """Truths ~ N(0, 1) given a mean m ~ N(0, 1) of two parameters; a 'posterior' of draws N(m, width^2)
    (the true posterior is N(m, 1): width < 1 is overconfident)."""
    m = rng.standard_normal((films, 2))
    truth = m + rng.standard_normal((films, 2))
    return truth, [mi + width * rng.standard_normal((draws, 2)) for mi in m]


def coverage(truth, draws, level=0.9):
    bounds = np.array([central_quantiles(d, level) for d in draws])
    return np.mean((truth >= bounds[:, 0]) & (truth <= bounds[:, 2]), axis=0)


@pytest.mark.parametrize("width", [0.5, 1.0, 2.0])
def test_the_factor_brings_overconfident_and_underconfident_intervals_to_their_level(width):
    rng = np.random.default_rng(3)
    truth, draws = toy_films(rng, 2000, width)  # the achieved coverage varies by ~0.7 points from set to set
    fitted = fit_calibration(truth, draws, 0.9)
    assert fitted.factors == pytest.approx([1.0 / width] * 2, rel=0.1)  # the true factor is 1 / width
    new_truth, new_draws = toy_films(rng, 2000, width)
    raw = coverage(new_truth, new_draws)
    box = (np.full(2, -50.0), np.full(2, 50.0))
    calibrated = coverage(new_truth, [fitted.apply(d, *box) for d in new_draws])
    assert np.all(np.abs(calibrated - 0.9) < 0.03), (raw, calibrated)
    if width == 0.5:
        assert np.all(raw < 0.65)  # the toy is as overconfident as it should be: P(|z| < 0.82) = 0.59


def test_spread_draws_spreads_the_percentiles_and_clips_to_the_box():
    rng = np.random.default_rng(0)
    draws = rng.uniform(0.2, 0.6, (1000, 2))
    low, median, high = central_quantiles(draws, 0.9)
    spread = spread_draws(draws, np.array([1.5, np.inf]), np.zeros(2), np.ones(2))
    s_low, s_median, s_high = central_quantiles(spread, 0.9)
    assert s_median[0] == pytest.approx(median[0])
    assert s_low[0] == pytest.approx(median[0] - 1.5 * (median[0] - low[0]))
    assert s_high[0] == pytest.approx(median[0] + 1.5 * (high[0] - median[0]))
    assert (s_low[1], s_high[1]) == (0.0, 1.0)  # an infinite factor: the whole box
    assert spread.min() >= 0.0 and spread.max() <= 1.0


def test_scores_and_the_conformal_rank():
    truth = np.array([[1.0], [0.0], [-2.0], [0.5]])
    low, median, high = np.full((4, 1), -1.0), np.zeros((4, 1)), np.full((4, 1), 2.0)
    assert conformal_scores(truth, low, median, high)[:, 0].tolist() == [0.5, 0.0, 2.0, 0.25]
    assert conformal_scores(np.array([[1.0]]), np.zeros((1, 1)), np.zeros((1, 1)), np.zeros((1, 1)))[0, 0] == np.inf
    scores = np.arange(1, 101, dtype=float)[:, None]  # 100 films: the ceil(101 * 0.9) = 91st smallest
    assert conformal_factor(scores, 0.9)[0] == 91.0
    assert np.isinf(conformal_factor(scores[:MIN_CALIBRATION_FILMS - 1], 0.9)).all()
    assert np.isinf(fit_calibration(np.zeros((0, 4)), [], 0.9).factors).all()


def test_the_calibration_films_are_a_fixed_fifth_of_the_ids():
    ids = [f"{k:016x}" for k in range(5000)]
    kept = [is_calibration_film(i) for i in ids]
    assert abs(np.mean(kept) - CALIBRATION_SHARE) < 0.02
    assert kept == [is_calibration_film(i) for i in ids]
