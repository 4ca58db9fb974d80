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
stopping); the prior is the box of `qdots.inference.forward.PARAMETERS`. The mass model, a choice between
three hypotheses, is not a dimension of the flow: a classifier gives its probabilities
(`qdots.inference.modelchoice`), trained on the same films and kept in the same `Posterior`. `ENSEMBLE` networks trained
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
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from labrig.files import atomic_path
from labrig.validate import InputError, count

from ..micrograph.choices import INFER_EXTRA, MAX_SAMPLES, MIN_TRAINING_FILMS
from .conformal import (
    CALIBRATION_SHARE,
    IntervalCalibration,
    central_quantiles,
    fit_calibration,
    is_calibration_film,
    spread_draws,
)
from .forward import MASS_MODELS, PARAMETERS
from .modelchoice import TEMPERATURES, MassModelChoice, fit_temperature, softmax, train_model_choice

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


def posterior_key(ids: list, ensemble: int = ENSEMBLE, seed: int = 0, replicates: list | None = None) -> str:
    """16 hex digits naming a posterior: the films it learnt from, the network and the training seed, and the
    replicate sets its joint calibration was fitted on."""
    import sbi

    from .modelchoice import HIDDEN, MAX_EPOCHS, PATIENCE

    text = json.dumps({"films": list(ids), "flow": FLOW, "ensemble": ensemble, "seed": seed, "sbi": sbi.__version__,
                       "calibration": [CALIBRATION_SHARE, CALIBRATION_SAMPLES, LEVEL],
                       "mass_models": [m.key for m in MASS_MODELS], "classifier": [HIDDEN, MAX_EPOCHS, PATIENCE],
                       "replicates": replicates or [], "joint": [list(JOINT_COUNTS), JOINT_CALIBRATION_PROPOSALS]},
                      sort_keys=True)
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
        with warnings.catch_warnings():  # shares that are 0 in most films have an IQR of 0: sbi calls them outliers
            warnings.filterwarnings("ignore", message="Data has extreme outliers")
            inference.append_simulations(torch.from_numpy(theta), torch.from_numpy(x))
            estimator = inference.train()
        members.append(inference.build_posterior(estimator))
    return members[0] if ensemble == 1 else EnsemblePosterior(members)


#: Observations per set the joint posterior's calibration is fitted for (`fit_joint_calibration`), and the
#: proposals of each joint posterior it draws.
JOINT_COUNTS, JOINT_CALIBRATION_PROPOSALS = (2, 4, 8), 2000


@dataclass(frozen=True)
class JointCalibration:
    """The calibration of posteriors given several observations of one sample, fitted on sets of replicate films
    (one deposition, several seeds): per count of observations in `counts`, the intervals' factors and the mass
    models' temperature.

    One network's errors are shared by every observation of a sample, so multiplying their posteriors narrows the
    intervals more than the data do; the single-observation calibration does not correct that, these do."""

    counts: tuple
    intervals: tuple
    temperatures: tuple
    groups: int

    def at(self, m: int) -> tuple[IntervalCalibration, float, int]:
        """The calibration for ``m`` observations: that of the largest fitted count at most ``m`` (for more than
        the largest, the largest's: an extrapolation), its temperature, and that count."""
        k = max([i for i, c in enumerate(self.counts) if c <= m], default=0)
        return self.intervals[k], float(self.temperatures[k]), int(self.counts[k])


@dataclass(frozen=True)
class Posterior:
    """The amortized posterior of ``qdots infer``: the trained networks and the calibration of their intervals,
    and the mass models' probabilities.

    Attributes
    ----------
    network : sbi posterior
        The networks (`train_posterior`) of the continuous parameters, trained on the films not kept for
        calibration, the mass model marginalised (each film has one of the three).
    calibration : IntervalCalibration
        The interval widths' factors, from the films kept out (`qdots.inference.conformal`).
    training_films : int
        Films the networks learnt from.
    mass_models : MassModelChoice
        P(mass model | observation) (`qdots.inference.modelchoice`), its temperature fitted on the films kept out.
    joint : JointCalibration or None
        The calibration of several observations (`fit_joint_calibration`); None when no replicate films were
        given: a joint posterior then takes the single observation's, which is too narrow (said where it is used).
    """

    network: object
    calibration: IntervalCalibration
    training_films: int
    mass_models: MassModelChoice
    joint: JointCalibration | None = None

    def model_probabilities(self, x_obs: np.ndarray) -> np.ndarray:
        """P(mass model | ``x_obs``), one per `MASS_MODELS`; ``x_obs`` (K,) one observation, or (m, K) several
        independent observations of one sample (pictures, or parts of one picture): with the models' equal prior,
        P(model | all) is proportional to the product of P(model | each), tempered by the joint calibration's
        temperature for m observations."""
        x_obs = np.atleast_2d(x_obs)
        log_p = np.log(np.clip(self.mass_models.probabilities(x_obs), 1e-300, 1.0)).sum(axis=0)
        temperature = self.joint.at(len(x_obs))[1] if self.joint is not None and len(x_obs) > 1 else 1.0
        return softmax(log_p[None, :] / temperature)[0]

    def sample_joint(self, observations: np.ndarray, n: int = 4000, seed: int = 0,
                     calibrated: bool = True) -> tuple[np.ndarray, float]:
        """``n`` draws (n, 4) given several independent observations (m, K) of one sample, spread by the joint
        calibration for m observations, and the effective number of draws behind them (`joint_draws`); one
        observation is `sample`."""
        observations = np.atleast_2d(np.asarray(observations, dtype=float))
        if len(observations) == 1:
            return self.sample(observations[0], n, seed, calibrated), float(n)
        draws, effective = joint_draws(self.network, observations, n, seed)
        if not calibrated:
            return draws, effective
        return spread_draws(draws, self.factors(len(observations)), *prior_bounds()), effective

    def factors(self, observations: int = 1) -> np.ndarray:
        """The intervals' spread factors for this many observations: the joint calibration's for several (when
        fitted), else the single observation's."""
        if observations > 1 and self.joint is not None:
            return self.joint.at(observations)[0].factors
        return self.calibration.factors

    def sample(self, x_obs: np.ndarray, n: int = 4000, seed: int = 0, calibrated: bool = True) -> np.ndarray:
        """``n`` draws (n, 4) at the observation ``x_obs``: the networks' own, spread by the calibration unless
        ``calibrated`` is False."""
        draws = sample_posterior(self.network, x_obs, n, seed)
        return self.calibrate(draws) if calibrated else draws

    def calibrate(self, draws: np.ndarray) -> np.ndarray:
        """The networks' ``draws`` (n, 4) spread by the calibration, inside the prior's box."""
        return self.calibration.apply(draws, *prior_bounds())


def prior_bounds() -> tuple[np.ndarray, np.ndarray]:
    """The prior's box: its lower and upper bounds, one per parameter of `PARAMETERS`."""
    return np.array([p.low for p in PARAMETERS]), np.array([p.high for p in PARAMETERS])


def fit_joint_calibration(posterior: Posterior, groups: list, counts: tuple = JOINT_COUNTS,
                          seed: int = 0) -> JointCalibration | None:
    """The calibration of joint posteriors from replicate sets ``groups``: each ``(theta, model, observations)``,
    the true parameters (4,), the true mass model's index and the observations (c, K) of c films of that
    deposition. For each count m of ``counts``, every set with at least m films gives a joint posterior of its
    first m observations: the intervals' conformal factors (`fit_calibration`) and the temperature of the
    product of the mass models' probabilities that minimises their log loss. None without sets."""
    if not groups:
        return None
    fitted, intervals, temperatures = [], [], []
    for m in counts:
        chosen = [g for g in groups if len(g[2]) >= m]
        if len(chosen) < 2:
            continue
        draws = [joint_draws(posterior.network, g[2][:m], CALIBRATION_SAMPLES, seed + k,
                             JOINT_CALIBRATION_PROPOSALS)[0] for k, g in enumerate(chosen)]
        intervals.append(fit_calibration(np.array([g[0] for g in chosen]), draws, LEVEL))
        log_p = np.array([np.log(np.clip(posterior.mass_models.probabilities(g[2][:m]), 1e-300, 1.0)).sum(axis=0)
                          for g in chosen])
        truth = np.array([g[1] for g in chosen])
        losses = [-np.mean(np.log(softmax(log_p / t)[np.arange(len(truth)), truth])) for t in TEMPERATURES]
        temperatures.append(float(TEMPERATURES[int(np.argmin(losses))]))
        fitted.append(m)
    if not fitted:
        return None
    return JointCalibration(tuple(fitted), tuple(intervals), tuple(temperatures), len(groups))


def calibrated_posterior(theta: np.ndarray, models: np.ndarray, x: np.ndarray, ids: list, *,
                         ensemble: int = ENSEMBLE, seed: int = 0, replicates: list | None = None) -> Posterior:
    """Train on the films ``ids`` not kept for calibration (`is_calibration_film`): the parameters' networks on
    ``theta`` and the mass models' classifier on ``models``; then fit the intervals' factors and the classifier's
    temperature on those kept (`qdots.inference.conformal.fit_calibration`, `modelchoice.fit_temperature`), and
    the joint posteriors' calibration on the replicate sets ``replicates`` (`fit_joint_calibration`)."""
    theta = np.asarray(theta, dtype=float)
    models = np.asarray(models, dtype=int)
    x = np.asarray(x, dtype=float)
    if len(ids) != len(theta) or len(x) != len(theta) or len(models) != len(theta):
        raise InputError(f"theta, models, x and ids must have one row per film, got {len(theta)}, {len(models)}, "
                         f"{len(x)} and {len(ids)}")
    kept = np.array([is_calibration_film(i) for i in ids], dtype=bool)
    network = train_posterior(theta[~kept], x[~kept], ensemble=ensemble, seed=seed)
    draws = [sample_posterior(network, row, CALIBRATION_SAMPLES, seed + k) for k, row in enumerate(x[kept])]
    choice = train_model_choice(x[~kept], models[~kept], ensemble=ensemble, seed=seed)
    single = Posterior(network, fit_calibration(theta[kept], draws, LEVEL), int((~kept).sum()),
                       fit_temperature(choice, x[kept], models[kept]))
    joint = fit_joint_calibration(single, replicates or [], seed=seed)
    return single if joint is None else replace(single, joint=joint)


def load_or_train(folder: str | os.PathLike, theta: np.ndarray, models: np.ndarray, x: np.ndarray, ids: list, *,
                  ensemble: int = ENSEMBLE, seed: int = 0, replicates: list | None = None) -> tuple[Posterior, bool]:
    """The `Posterior` learnt from the films ``ids``: loaded from ``folder/posteriors`` when trained before, else
    made (`calibrated_posterior`) and saved there (atomically). Returns (posterior, whether it was loaded)."""
    torch = require_sbi()
    replicates = replicates or []
    key = posterior_key(ids, ensemble, seed, [[list(map(float, g[0])), int(g[1]), len(g[2])] for g in replicates])
    path = Path(folder) / "posteriors" / f"{key}.pt"
    if path.is_file():
        try:
            saved = torch.load(path, weights_only=False)
            if isinstance(saved, Posterior):
                return saved, True
        except Exception:  # a damaged cache file is trained again and replaced
            pass
    posterior = calibrated_posterior(theta, models, x, ids, ensemble=ensemble, seed=seed, replicates=replicates)
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


#: Proposals of the joint posterior's importance sampling (`joint_draws`).
JOINT_PROPOSALS = 20_000


def joint_draws(network, observations: np.ndarray, n: int, seed: int = 0,
                proposals: int = JOINT_PROPOSALS) -> tuple[np.ndarray, float]:
    """``n`` draws from the posterior given independent observations ``observations`` (m, K) of one sample.

    With a uniform prior, ``p(theta | x_1..x_m)`` is proportional to the product of the single-observation
    posteriors ``q(theta | x_i)`` inside the prior's box (each is the likelihood times the prior). The networks
    give each ``q``'s density and draws; the product is sampled by importance resampling from the mixture of the
    ``q``s (``proposals`` draws, an equal share from each), which covers wherever the product lies. Returns
    the draws and the effective number of proposals behind them (Kish's ``(sum w)^2 / sum w^2``)."""
    torch = require_sbi()
    n = count("samples", n, 1, MAX_SAMPLES)
    observations = np.atleast_2d(np.asarray(observations, dtype=float))
    share = max(1, proposals // len(observations))
    theta = np.vstack([sample_posterior(network, x, share, seed + k) for k, x in enumerate(observations)])
    t = torch.as_tensor(theta.astype(np.float32))
    with torch.no_grad():
        log_q = np.array([network.log_prob(t, x=torch.as_tensor(x.astype(np.float32)[None, :]),
                                           norm_posterior=False).numpy() for x in observations], dtype=float)
    log_q = np.where(np.isfinite(log_q), log_q, -np.inf)
    top = np.max(log_q, axis=0)
    mixture = top + np.log(np.mean(np.exp(log_q - np.where(np.isfinite(top), top, 0.0)), axis=0))
    log_w = np.sum(log_q, axis=0) - mixture
    log_w = np.where(np.isfinite(log_w), log_w, -np.inf)
    w = np.exp(log_w - np.max(log_w))
    w /= w.sum()
    rng = np.random.default_rng([5604, seed])
    return theta[rng.choice(len(theta), n, p=w)], float(1.0 / np.sum(w**2))


#: An interval's end this close to its prior's bound (a share of the prior's width) is taken to the bound.
EDGE = 0.02


def credible_intervals(samples: np.ndarray, level: float = LEVEL) -> list[dict]:
    """Per parameter: ``key``, ``label``, ``median``, ``low`` and ``high`` of the central ``level`` interval, and
    the prior's bounds ``prior_low``, ``prior_high`` and the interval's share of them (``width_share``).

    An end within `EDGE` of the prior's width from its bound is taken to the bound (``at_bound``: ``"low"``,
    ``"high"``, ``"both"`` or ``""``): a posterior piled against a bound (no drag, the thesis's figures' -3) says
    the value may be the bound itself, which a central interval would leave out by a hair. The interval only grows,
    so what its calibration holds still holds."""
    rows = []
    for p, low, median, high in zip(PARAMETERS, *central_quantiles(samples, level)):
        margin = EDGE * (p.high - p.low)
        at_low, at_high = low - p.low <= margin, p.high - high <= margin
        low, high = (p.low if at_low else float(low)), (p.high if at_high else float(high))
        rows.append({"key": p.key, "label": p.label, "median": float(median), "low": float(low), "high": float(high),
                     "prior_low": p.low, "prior_high": p.high, "width_share": float((high - low) / (p.high - p.low)),
                     "at_bound": "both" if at_low and at_high else "low" if at_low else "high" if at_high else ""})
    return rows
