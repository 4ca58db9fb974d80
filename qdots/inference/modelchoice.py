"""The mass model as a model choice: posterior probabilities of equal masses, masses ~ d^2 and ~ d^3.

The thesis asks whether size spread, effective mass or too little damping breaks a polydisperse monolayer;
its three mass hypotheses (`qdots.inference.forward.MASS_MODELS`) sit at fixed exponents, where a central
interval on a continuous exponent can never reach them. So the library's films draw one of the three models
with equal probability, and a classifier learns ``P(model | measures, sigma, coverage)``: trained by
cross-entropy on films drawn from the prior, its outputs are the posterior probabilities of the models under
that equal prior (the classifier approach to model choice, as in Pudlo et al. 2016 and Radev et al. 2021;
likelihood-free, on the same films as the posterior's networks).

The classifier: `ENSEMBLE` small networks (two hidden layers of `HIDDEN` units, measures z-scored), each
trained with early stopping on a tenth of its films, their probabilities averaged. Networks are often
over-confident; the films kept out of the training for the intervals' calibration (`qdots.inference.conformal`)
fit one temperature that divides the averaged log-probabilities (temperature scaling, Guo et al. 2017), so
that a probability of 0.8 is right about 80 % of the time on films drawn as the library's are;
`qdots.inference.calibration` checks that on held-out films (`reliability_table`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from labrig.validate import InputError, count

from .forward import MASS_MODELS

#: Networks averaged, their hidden units, most training epochs, epochs without improvement before stopping.
ENSEMBLE, HIDDEN, MAX_EPOCHS, PATIENCE = 3, 64, 400, 25
#: The temperatures tried when fitting the calibration (a grid in log T).
TEMPERATURES = np.exp(np.linspace(math.log(0.25), math.log(8.0), 161))


@dataclass(frozen=True)
class MassModelChoice:
    """A trained classifier of the mass model: ``probabilities(x)`` gives P(model | x) per `MASS_MODELS`.

    Attributes
    ----------
    networks : list of torch modules
    mean, scale : ndarray (K,)
        The z-scoring of the observations (from the training films).
    temperature : float
        Divides the averaged log-probabilities (1: as trained; fitted on the calibration films).
    """

    networks: list
    mean: np.ndarray
    scale: np.ndarray
    temperature: float = 1.0

    def log_probabilities(self, x: np.ndarray) -> np.ndarray:
        """The averaged networks' log-probabilities (n, models) at the observations ``x`` (n, K), before the
        temperature."""
        import torch

        x = np.atleast_2d(np.asarray(x, dtype=float))
        z = torch.as_tensor(((x - self.mean) / self.scale).astype(np.float32))
        with torch.no_grad():
            p = np.mean([torch.softmax(net(z), dim=1).numpy() for net in self.networks], axis=0)
        return np.log(np.clip(p.astype(float), 1e-12, 1.0))

    def probabilities(self, x: np.ndarray) -> np.ndarray:
        """P(model | x), (n, models), calibrated by the temperature."""
        return softmax(self.log_probabilities(x) / self.temperature)


def softmax(logits: np.ndarray) -> np.ndarray:
    """Row-wise softmax of ``logits`` (n, m)."""
    z = logits - logits.max(axis=1, keepdims=True)
    e = np.exp(z)
    return e / e.sum(axis=1, keepdims=True)


def network(inputs: int, seed: int):
    """One classifier network: ``inputs`` -> two hidden layers of `HIDDEN` -> one logit per mass model."""
    import torch

    torch.manual_seed(seed)
    return torch.nn.Sequential(torch.nn.Linear(inputs, HIDDEN), torch.nn.ReLU(), torch.nn.Linear(HIDDEN, HIDDEN),
                               torch.nn.ReLU(), torch.nn.Linear(HIDDEN, len(MASS_MODELS)))


def train_network(z: np.ndarray, models: np.ndarray, seed: int):
    """Train one network on z-scored observations ``z`` and model indices ``models`` (Adam, mini-batches of 128,
    a tenth of the films held out for early stopping); returns it at its best held-out loss."""
    import copy

    import torch

    rng = np.random.default_rng(seed)
    order = rng.permutation(len(z))
    held = order[: max(1, len(z) // 10)]
    fit = order[max(1, len(z) // 10):]
    net = network(z.shape[1], seed)
    optimiser = torch.optim.Adam(net.parameters(), lr=1e-3, weight_decay=1e-4)
    loss = torch.nn.CrossEntropyLoss()
    zt, mt = torch.as_tensor(z.astype(np.float32)), torch.as_tensor(models.astype(np.int64))
    best, best_state, since = math.inf, copy.deepcopy(net.state_dict()), 0
    for _ in range(MAX_EPOCHS):
        net.train()
        shuffled = rng.permutation(fit)
        for start in range(0, len(shuffled), 128):
            batch = torch.as_tensor(shuffled[start:start + 128])
            optimiser.zero_grad()
            loss(net(zt[batch]), mt[batch]).backward()
            optimiser.step()
        net.eval()
        with torch.no_grad():
            value = float(loss(net(zt[held]), mt[held]))
        if value < best - 1e-4:
            best, best_state, since = value, copy.deepcopy(net.state_dict()), 0
        else:
            since += 1
            if since >= PATIENCE:
                break
    net.load_state_dict(best_state)
    net.eval()
    return net


def train_model_choice(x: np.ndarray, models: np.ndarray, *, ensemble: int = ENSEMBLE,
                       seed: int = 0) -> MassModelChoice:
    """Train the classifier on observations ``x`` (N, K) of films whose mass models are ``models`` (N,), indices in
    `MASS_MODELS`; its temperature is 1 (`fit_temperature` calibrates it)."""
    from .posterior import require_sbi

    require_sbi()
    ensemble = count("ensemble", ensemble, 1, 10)
    x = np.asarray(x, dtype=float)
    models = np.asarray(models, dtype=int)
    if x.ndim != 2 or len(models) != len(x) or len(x) < 2 * len(MASS_MODELS):
        raise InputError(f"the mass-model classifier needs at least {2 * len(MASS_MODELS)} films, one model each, "
                         f"got x {x.shape} and {len(models)} models")
    if models.min() < 0 or models.max() >= len(MASS_MODELS):
        raise InputError(f"mass models must be indices in [0, {len(MASS_MODELS) - 1}]")
    mean, scale = x.mean(axis=0), x.std(axis=0)
    scale = np.where(scale > 0, scale, 1.0)
    z = (x - mean) / scale
    return MassModelChoice([train_network(z, models, seed + k) for k in range(ensemble)], mean, scale)


def fit_temperature(choice: MassModelChoice, x: np.ndarray, models: np.ndarray) -> MassModelChoice:
    """``choice`` with the temperature (of `TEMPERATURES`) that minimises the log loss of films ``x`` whose true
    models are ``models``: films kept out of its training."""
    log_p = choice.log_probabilities(x)
    models = np.asarray(models, dtype=int)
    losses = [-np.mean(np.log(softmax(log_p / t)[np.arange(len(models)), models])) for t in TEMPERATURES]
    return MassModelChoice(choice.networks, choice.mean, choice.scale, float(TEMPERATURES[int(np.argmin(losses))]))


def reliability_table(probabilities: np.ndarray, models: np.ndarray, edges=(0.0, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0)
                      ) -> list[dict]:
    """How often the most probable model is right, by its probability: rows ``low``, ``high``, ``films``,
    ``stated`` (the mean probability given) and ``right`` (the share whose true model it was)."""
    probabilities = np.asarray(probabilities, dtype=float)
    models = np.asarray(models, dtype=int)
    top = probabilities.argmax(axis=1)
    given = probabilities.max(axis=1)
    rows = []
    for low, high in zip(edges[:-1], edges[1:]):
        inside = (given >= low) & ((given < high) | (high == edges[-1]))
        rows.append({"low": low, "high": high, "films": int(inside.sum()),
                     "stated": float(given[inside].mean()) if inside.any() else math.nan,
                     "right": float(np.mean(top[inside] == models[inside])) if inside.any() else math.nan})
    return rows


def confusion_table(probabilities: np.ndarray, models: np.ndarray) -> np.ndarray:
    """(true model, chosen model) counts: the most probable model of each film against its true one."""
    out = np.zeros((len(MASS_MODELS), len(MASS_MODELS)), dtype=int)
    np.add.at(out, (np.asarray(models, dtype=int), np.asarray(probabilities).argmax(axis=1)), 1)
    return out
