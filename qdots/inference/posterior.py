"""The amortized posterior of ``qdots infer``: neural posterior estimation (sbi) on the library's films.

Why neural posterior estimation (`sbi`'s NPE), not ABC-SMC (pyabc) or an emulator with a synthetic
likelihood: NPE learns ``p(parameters | measures, sigma, coverage)`` once from films drawn from the
prior, then answers any micrograph by a forward pass; the size spread and coverage come from the
micrograph, so they are inputs of the network, and a second image costs no simulation at all. ABC-SMC
spends its simulations on one observation (thousands per image, at 2 s a film); a synthetic likelihood
needs many seeds at every point an MCMC visits. The library's films are independent of any image,
which is what makes them reusable.

The network: a masked autoregressive flow (sbi's ``"maf"``, 50 hidden features, 5 transforms) with the
measures and parameters z-scored, trained with sbi's defaults (10 % of the films held out for early
stopping); the prior is the box of `qdots.inference.forward.PARAMETERS`. `ENSEMBLE` networks trained
from different seeds are averaged (sbi's ``EnsemblePosterior``): one network trained on a thousand films
is overconfident, which the calibration measures, and averaging more networks does not cure it. So a
fifth of the films is kept out of the training and calibrates the intervals' widths
(`qdots.inference.conformal`): a `Posterior` is the networks and that calibration. A trained posterior is
saved in the library (``posteriors/<key>.pt``), keyed by the films it learnt from and these settings, and
loaded when asked for again. torch and sbi are the optional extra ``infer``: ``pip install torch==2.13.0 'nanodisorder[infer]'``.
"""

from __future__ import annotations

import hashlib
import json
import os
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from labrig.files import atomic_path
from labrig.validate import InputError, count

from ..micrograph.choices import INFER_EXTRA, MAX_SAMPLES, MIN_TRAINING_FILMS
from .conformal import CALIBRATION_SHARE, IntervalCalibration, central_quantiles, fit_calibration, is_calibration_film
from .forward import PARAMETERS

#: Networks averaged in one posterior, their flow, and the threads torch may use (one: on a busy 2-core machine
#: two threads made a training 10-30x slower, measured).
ENSEMBLE, FLOW, THREADS = 3, "maf", 1
#: Draws per calibration film; the credible level of the intervals.
CALIBRATION_SAMPLES, LEVEL = 1000, 0.9


def require_sbi():
    """Import torch and sbi; `InputError` (one line) saying how to install them when they are missing."""
    try:
        import sbi  # noqa: F401
        import torch
    except ImportError:
        raise InputError(INFER_EXTRA) from None
    torch.set_num_threads(min(THREADS, os.cpu_count() or 1))
    return torch


class NoTracking:
    """An sbi tracker that keeps nothing: without one, sbi writes TensorBoard logs into ``./sbi-logs`` of
    whatever folder the user is in."""

    log_dir = None

    def log_metric(self, name, value, step=None) -> None:
        """Discard a training metric."""

    def log_metrics(self, metrics, step=None) -> None:
        """Discard training metrics."""

    def log_params(self, params) -> None:
        """Discard the training's parameters."""

    def add_figure(self, name, figure, step=None) -> None:
        """Discard a figure."""

    def flush(self) -> None:
        """Nothing to write."""


def prior():
    """The prior of the parameters: uniform over the box of `PARAMETERS` (sbi's ``BoxUniform``)."""
    torch = require_sbi()
    from sbi.utils import BoxUniform

    return BoxUniform(torch.tensor([p.low for p in PARAMETERS], dtype=torch.float32),
                      torch.tensor([p.high for p in PARAMETERS], dtype=torch.float32))


def posterior_key(ids: list, ensemble: int = ENSEMBLE, seed: int = 0) -> str:
    """16 hex digits naming a posterior: the films it learnt from, the network and the training seed."""
    import sbi

    text = json.dumps({"films": list(ids), "flow": FLOW, "ensemble": ensemble, "seed": seed, "sbi": sbi.__version__,
                       "calibration": [CALIBRATION_SHARE, CALIBRATION_SAMPLES, LEVEL]}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def train_posterior(theta: np.ndarray, x: np.ndarray, *, ensemble: int = ENSEMBLE, seed: int = 0):
    """Train ``ensemble`` NPE networks on (``theta``, ``x``) and return their posterior.

    Parameters
    ----------
    theta : ndarray (N, 4)
        Parameters of the films (inside the prior's box).
    x : ndarray (N, K)
        What each film gives: its summaries and its conditions (`qdots.inference.library.observation`).
    ensemble : int
        Networks averaged, in [1, 10].
    seed : int
        Seed of the first network's training (the others take the next ones).
    """
    torch = require_sbi()
    from sbi.inference import NPE
    from sbi.inference.posteriors import EnsemblePosterior

    ensemble = count("ensemble", ensemble, 1, 10)
    theta = np.asarray(theta, dtype=np.float32)
    x = np.asarray(x, dtype=np.float32)
    if theta.ndim != 2 or theta.shape[1] != len(PARAMETERS) or len(x) != len(theta) or len(theta) < MIN_TRAINING_FILMS:
        raise InputError(f"training needs at least {MIN_TRAINING_FILMS} films with {len(PARAMETERS)} parameters each, "
                         f"got theta {theta.shape} and x {x.shape}")
    box = prior()
    members = []
    for k in range(ensemble):
        torch.manual_seed(seed + k)
        inference = NPE(prior=box, density_estimator=FLOW, show_progress_bars=False, tracker=NoTracking())
        inference.append_simulations(torch.from_numpy(theta), torch.from_numpy(x))
        with warnings.catch_warnings():  # shares that are 0 in most films have an IQR of 0: sbi calls them outliers
            warnings.filterwarnings("ignore", message="Data has extreme outliers")
            estimator = inference.train()
        members.append(inference.build_posterior(estimator))
    return members[0] if ensemble == 1 else EnsemblePosterior(members)


@dataclass(frozen=True)
class Posterior:
    """The amortized posterior of ``qdots infer``: the trained networks and the calibration of their intervals.

    Attributes
    ----------
    network : sbi posterior
        The networks (`train_posterior`), trained on the films not kept for calibration.
    calibration : IntervalCalibration
        The interval widths' factors, from the films kept out (`qdots.inference.conformal`).
    training_films : int
        Films the networks learnt from.
    """

    network: object
    calibration: IntervalCalibration
    training_films: int

    def sample(self, x_obs: np.ndarray, n: int = 4000, seed: int = 0, calibrated: bool = True) -> np.ndarray:
        """``n`` draws (n, 4) at the observation ``x_obs``: the networks' own, spread by the calibration unless
        ``calibrated`` is False."""
        draws = sample_posterior(self.network, x_obs, n, seed)
        return self.calibrate(draws) if calibrated else draws

    def calibrate(self, draws: np.ndarray) -> np.ndarray:
        """The networks' ``draws`` (n, 4) spread by the calibration, inside the prior's box."""
        return self.calibration.apply(draws, np.array([p.low for p in PARAMETERS]),
                                      np.array([p.high for p in PARAMETERS]))


def calibrated_posterior(theta: np.ndarray, x: np.ndarray, ids: list, *, ensemble: int = ENSEMBLE,
                         seed: int = 0) -> Posterior:
    """Train on the films ``ids`` not kept for calibration (`is_calibration_film`), and fit the intervals'
    factors on those kept (`qdots.inference.conformal.fit_calibration`)."""
    theta = np.asarray(theta, dtype=float)
    x = np.asarray(x, dtype=float)
    if len(ids) != len(theta) or len(x) != len(theta):
        raise InputError(f"theta, x and ids must have one row per film, got {len(theta)}, {len(x)} and {len(ids)}")
    kept = np.array([is_calibration_film(i) for i in ids], dtype=bool)
    network = train_posterior(theta[~kept], x[~kept], ensemble=ensemble, seed=seed)
    draws = [sample_posterior(network, row, CALIBRATION_SAMPLES, seed + k) for k, row in enumerate(x[kept])]
    return Posterior(network, fit_calibration(theta[kept], draws, LEVEL), int((~kept).sum()))


def load_or_train(folder: str | os.PathLike, theta: np.ndarray, x: np.ndarray, ids: list, *,
                  ensemble: int = ENSEMBLE, seed: int = 0) -> tuple[Posterior, bool]:
    """The `Posterior` learnt from the films ``ids``: loaded from ``folder/posteriors`` when trained before, else
    made (`calibrated_posterior`) and saved there (atomically). Returns (posterior, whether it was loaded)."""
    torch = require_sbi()
    path = Path(folder) / "posteriors" / f"{posterior_key(ids, ensemble, seed)}.pt"
    if path.is_file():
        try:
            saved = torch.load(path, weights_only=False)
            if isinstance(saved, Posterior):
                return saved, True
        except Exception:  # a damaged cache file is trained again and replaced
            pass
    posterior = calibrated_posterior(theta, x, ids, ensemble=ensemble, seed=seed)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        torch.save(posterior, tmp)
    return posterior, False


def sample_posterior(posterior, x_obs: np.ndarray, n: int = 4000, seed: int = 0) -> np.ndarray:
    """``n`` draws (n, 4) from the posterior at the observation ``x_obs``."""
    torch = require_sbi()
    n = count("samples", n, 1, MAX_SAMPLES)
    torch.manual_seed(seed)
    x = torch.as_tensor(np.asarray(x_obs, dtype=np.float32)[None, :])
    return posterior.sample((n,), x=x, show_progress_bars=False).numpy().astype(float)


def credible_intervals(samples: np.ndarray, level: float = LEVEL) -> list[dict]:
    """Per parameter: ``key``, ``label``, ``median``, ``low`` and ``high`` of the central ``level`` interval, and
    the prior's bounds ``prior_low``, ``prior_high`` and the interval's share of them (``width_share``)."""
    rows = []
    for p, low, median, high in zip(PARAMETERS, *central_quantiles(samples, level)):
        rows.append({"key": p.key, "label": p.label, "median": float(median), "low": float(low), "high": float(high),
                     "prior_low": p.low, "prior_high": p.high, "width_share": float((high - low) / (p.high - p.low))})
    return rows
