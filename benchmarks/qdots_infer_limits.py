"""qdots infer: why more pictures of one sample hardly narrow its intervals (the library's own error against a film's).

`qdots infer` multiplies the posteriors of several observations of one sample; calibrated on replicate films, the
product holds the truth but does not narrow (`benchmarks.qdots_infer`, its observations table). This benchmark
measures why, with a forward model independent of the posterior's networks: an emulator of the six summaries'
mean and covariance given the parameters, the mass model and the film's conditions, trained on the training
films shipped with the package (a synthetic likelihood; Wood 2010).

* **The library's error against a film's noise.** The emulator's mean is trained on 600, 1,200 and all usable
  training films (two draws each). On replicate sets (one deposition, 8 seeds each: the 60 shipped and the
  ``TEST_GROUPS`` held-out of `benchmarks.qdots_infer`) the mean of a set's 8 residuals has the variance
  ``error^2 + noise^2 / 8``; the seed noise comes from the spread within the sets, so the error of the learnt
  mean is measured without any truth but the films. An error shared by every observation of a sample is the
  floor no number of pictures goes below.
* **The posterior of m observations** (m = 1, 2, 4, 8) on the held-out sets: the likelihood of the mean of
  their summaries, Gaussian with the covariance ``lambda S + (1 - lambda) S / m`` (S the emulator's covariance of
  one film, ``lambda`` the share of it that is the emulator's own error, shared; fitted on the shipped sets by
  maximum likelihood), drawn by importance sampling from the prior (``PROPOSALS`` per mass model). Once with the
  emulator taken as exact (``lambda = 0``), once with its error.
* **What the summaries could tell with an exact forward model**: observations drawn from the emulator itself at
  the held-out sets' truths and conditions (so the model is exact by construction), m = 1 to 32; then the same
  with the measures the posterior leaves out (`MEASURE_SETS`: the nearest gap and the g(r) peak, which a diameter
  2 % off moves; psi6 global, the aggregates and the largest cluster, which depend on the film's size and the
  picture's edge), each with its own emulator: how much a picture could tell if they were read as a board reads them.

Run: ``python -m benchmarks.qdots_infer_limits [--quick]`` (needs the ``infer`` extra; the held-out sets are those
of `benchmarks.qdots_infer`, simulated there or here when missing: about 10 minutes on 2 cores).
"""

from __future__ import annotations

import math
import time

import numpy as np

from qdots.inference.conformal import is_calibration_film
from qdots.inference.forward import (
    CONDITIONS,
    MASS_KEY,
    MASS_MODELS,
    MEASURES,
    PARAMETERS,
    SUMMARIES,
    condition_keys,
    mass_model_index,
)
from qdots.inference.library import build_replicates, shipped_replicates, shipped_rows, usable_row
from qdots.inference.posterior import credible_intervals, prior_bounds

from .qdots_infer import TEST_FIRST, TEST_GROUPS, held_out_folder, pct
from .report import Headline, Note, Table, cli

#: The code this benchmark measures (besides itself).
MEASURED_CODE = ("qdots/inference", "benchmarks/qdots_infer.py")
#: Training films of the learning curve (None: all usable ones), draws per size, and the emulator's folds.
SIZES, DRAWS, FOLDS = (600, 1200, None), 2, 5
#: Observations per set of the posterior table, and of the exact-model table.
COUNTS, EXACT_COUNTS = (1, 2, 4, 8), (1, 4, 16, 32)
#: Proposals per mass model of the importance sampling (the exact-model table, whose posteriors are narrower, draws
#: `EXACT_MORE` times as many); the shares of shared error tried when fitting it.
PROPOSALS, EXACT_MORE, SHARES = 20_000, 10, np.round(np.linspace(0.0, 0.9, 19), 2)
#: Width of the emulator's hidden layers, films per batch, epochs without improvement before stopping.
HIDDEN, BATCH, PATIENCE = 128, 64, 50
#: Sets of measures of the exact-model table of more measures: the six the posterior uses with those it leaves out.
MEASURE_SETS = (("+ nearest gap, g(r) peak position", (*SUMMARIES, "mean_gap", "gr_peak_diameters")),
                ("+ g(r) peak height, psi6 global, aggregates, largest cluster",
                 (*SUMMARIES, "gr_peak_height", "psi6_global", "aggregates", "largest_share")),
                ("all twelve measures", tuple(MEASURES)))
#: Observations per set of the measure sets' table.
MEASURE_COUNTS = (1, 4, 16)
C = len(CONDITIONS)


def film_arrays(rows: list[dict], measures=SUMMARIES) -> tuple[np.ndarray, np.ndarray, np.ndarray, list]:
    """(theta, mass models, x, run ids) of the usable ``rows`` with every one of ``measures`` finite; x holds the
    measures then the film's own conditions (`qdots.inference.library.training_arrays` for other measures)."""
    rows = [r for r in rows if usable_row(r) and all(r.get(k) is not None and math.isfinite(r[k]) for k in measures)]
    theta = np.array([[r[p.key] for p in PARAMETERS] for r in rows], dtype=float).reshape(-1, len(PARAMETERS))
    models = np.array([mass_model_index(r[MASS_KEY]) for r in rows], dtype=int)
    x = np.array([[r[k] for k in measures] + [r[f"film_{c}"] for c in condition_keys()] for r in rows],
                 dtype=float).reshape(-1, len(measures) + C)
    return theta, models, x, [r["run"] for r in rows]


def film_sets(rows: list[dict], measures=SUMMARIES) -> list:
    """Replicate films as sets, ``(theta, mass model, x)`` per group with 2 usable films or more
    (`qdots.inference.library.replicate_groups` for other measures)."""
    groups: dict[int, list[dict]] = {}
    for row in rows:
        groups.setdefault(int(row["group"]), []).append(row)
    out = []
    for group in sorted(groups):
        theta, models, x, _ = film_arrays(sorted(groups[group], key=lambda r: r["copy"]), measures)
        if len(x) >= 2:
            out.append((theta[0], int(models[0]), x))
    return out


def emulator_inputs(theta: np.ndarray, model, conditions: np.ndarray) -> np.ndarray:
    """The emulator's inputs: the parameters and conditions scaled to [-1, 1] over their prior's range, the mass
    model one-hot (``model`` an index or one per row)."""
    theta = np.atleast_2d(theta)
    n = len(theta)
    low, high = prior_bounds()
    c_low, c_high = np.array([c.low for c in CONDITIONS]), np.array([c.high for c in CONDITIONS])
    onehot = np.zeros((n, len(MASS_MODELS)))
    onehot[np.arange(n), np.broadcast_to(np.asarray(model), (n,))] = 1.0
    scaled = (np.broadcast_to(conditions, (n, len(CONDITIONS))) - c_low) / (c_high - c_low)
    return np.hstack([(theta - low) / (high - low) * 2 - 1, onehot, scaled * 2 - 1]).astype(np.float32)


def network(out: int, inputs: int):
    import torch

    return torch.nn.Sequential(torch.nn.Linear(inputs, HIDDEN), torch.nn.SiLU(), torch.nn.Linear(HIDDEN, HIDDEN),
                               torch.nn.SiLU(), torch.nn.Linear(HIDDEN, out))


def fit(net, loss, u: np.ndarray, y: np.ndarray, seed: int, max_epochs: int):
    """Train ``net`` on (u, y) with AdamW, a tenth held out for early stopping; the best state is kept."""
    import torch

    torch.manual_seed(seed)
    order = np.random.default_rng(seed).permutation(len(u))
    held, kept = order[: len(u) // 10], order[len(u) // 10:]
    ut, yt, uv, yv = (torch.as_tensor(a) for a in (u[kept], y[kept], u[held], y[held]))
    optimiser = torch.optim.AdamW(net.parameters(), 1e-3, weight_decay=1e-4)
    generator = torch.Generator().manual_seed(seed)
    best, state, waited = np.inf, None, 0
    for _ in range(max_epochs):
        for batch in torch.randperm(len(ut), generator=generator).split(BATCH):
            value = loss(net(ut[batch]), yt[batch]).mean()
            optimiser.zero_grad()
            value.backward()
            optimiser.step()
        with torch.no_grad():
            score = float(loss(net(uv), yv).mean())
        if score < best - 1e-5:
            best, state, waited = score, {k: t.clone() for k, t in net.state_dict().items()}, 0
        elif (waited := waited + 1) > PATIENCE:
            break
    net.load_state_dict(state)
    return net


def squared_error(prediction, target):
    return ((prediction - target) ** 2).sum(-1)


def cholesky_factor(raw):
    """Lower-triangular factors (n, k, k) with a positive diagonal from the network's raw outputs (n, k(k+1)/2)."""
    import torch

    k = int(round((math.sqrt(8 * raw.shape[1] + 1) - 1) / 2))
    rows, cols = np.tril_indices(k)
    factor = torch.zeros(len(raw), k, k)
    factor[:, rows, cols] = raw
    diagonal = torch.diagonal(factor, dim1=1, dim2=2)
    return factor - torch.diag_embed(diagonal) + torch.diag_embed(torch.nn.functional.softplus(diagonal) + 1e-4)


def gaussian_loss(raw, residual):
    import torch

    return -torch.distributions.MultivariateNormal(torch.zeros(residual.shape[-1]),
                                                   scale_tril=cholesky_factor(raw)).log_prob(residual)


class Emulator:
    """The six summaries' mean (an ensemble of ``FOLDS`` networks, each trained without one fold) and covariance (a
    network fitted to the folds' out-of-fold residuals, so that it holds the mean's own error as well as the seeds'),
    in units of each summary's spread over the library."""

    def __init__(self, u: np.ndarray, y: np.ndarray, seed: int = 0, folds: int = FOLDS, max_epochs: int = 3000):
        import torch

        k_out = y.shape[1]
        parts = np.array_split(np.random.default_rng(seed).permutation(len(u)), folds)
        self.means, residual = [], np.zeros_like(y)
        for k, part in enumerate(parts):
            rest = np.setdiff1d(np.arange(len(u)), part)
            net = fit(network(k_out, u.shape[1]), squared_error, u[rest], y[rest], seed + k, max_epochs)
            with torch.no_grad():
                residual[part] = y[part] - net(torch.as_tensor(u[part])).numpy()
            self.means.append(net)
        self.covariance = fit(network(k_out * (k_out + 1) // 2, u.shape[1]), gaussian_loss, u, residual, seed + folds,
                              max_epochs)

    def moments(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Mean (n, k) and covariance (n, k, k) of one film's measures at the inputs ``u``."""
        import torch

        with torch.no_grad():
            x = torch.as_tensor(u)
            mean = np.mean([net(x).numpy() for net in self.means], axis=0).astype(float)
            factor = cholesky_factor(self.covariance(x))
            return mean, (factor @ factor.transpose(1, 2)).numpy().astype(float)


def gaussian_log_density(r: np.ndarray, cov: np.ndarray) -> np.ndarray:
    factor = np.linalg.cholesky(cov)
    z = np.linalg.solve(factor, r[..., None])[..., 0]
    return (-0.5 * (z**2).sum(-1) - np.log(np.diagonal(factor, axis1=-2, axis2=-1)).sum(-1)
            - 0.5 * r.shape[-1] * np.log(2 * np.pi))


def set_moments(emulator: Emulator, theta: np.ndarray, model: int, x: np.ndarray, scale) -> tuple:
    """Per film of a set: its residual at the truth (m, k) and the emulator's covariance (m, k, k)."""
    mean, cov = emulator.moments(emulator_inputs(np.repeat(theta[None], len(x), 0), model, x[:, -C:]))
    return (x[:, :-C] - scale[0]) / scale[1] - mean, cov


def library_error(sets: list, scale, emulator_of) -> np.ndarray:
    """The error of a learnt mean (one per measure), from replicate ``sets``: the spread of the sets' mean residuals with the
    seeds' share (the spread within the sets over their size) taken out."""
    means, noise = [], []
    for theta, model, x in sets:
        z = (x[:, :-C] - scale[0]) / scale[1]
        means.append((z - emulator_of(theta, model, x)).mean(axis=0))
        noise.append(z.var(axis=0, ddof=1) / len(x))
    return np.sqrt(np.maximum(np.var(means, axis=0) - np.mean(noise, axis=0), 0.0))


def seed_noise(sets: list, scale) -> np.ndarray:
    """One film's seed spread per measure, in the measures' units: the root mean variance within the sets."""
    return np.sqrt(np.mean([((x[:, :-C] - scale[0]) / scale[1]).var(axis=0, ddof=1) for _, _, x in sets], axis=0))


def fitted_share(emulator: Emulator, sets: list, scale) -> float:
    """The share ``lambda`` of one film's covariance that is shared by a set's films (the emulator's error), by
    maximum likelihood over `SHARES` of the sets' mean residuals."""
    total = np.zeros(len(SHARES))
    for theta, model, x in sets:
        r, cov = set_moments(emulator, theta, model, x, scale)
        mean_r, mean_cov, m = r.mean(axis=0), cov.mean(axis=0), len(x)
        total += [gaussian_log_density(mean_r, (s + (1 - s) / m) * mean_cov) for s in SHARES]
    return float(SHARES[int(np.argmax(total))])


def posterior_rows(emulator: Emulator, sets: list, scale, share: float, counts, proposals: int, seed: int = 0,
                   exact: bool = False) -> list:
    """Per m of ``counts``: the coverage and width (one per parameter) of the 90 % intervals on ``sets``, the share of
    sets whose most probable mass model is theirs, the mean probability given to it, and the smallest effective
    number of proposals. ``exact``: the sets' observations are drawn from the emulator at their truths."""
    rng = np.random.default_rng([5620, seed])
    low, high = prior_bounds()
    draws = low + (high - low) * rng.random((proposals, len(PARAMETERS)))
    found = {m: ([], [], [], [], []) for m in counts}
    for theta, model, x in sets:
        conditions = x[:, -C:].mean(axis=0)
        moments = [emulator.moments(emulator_inputs(draws, j, conditions)) for j in range(len(MASS_MODELS))]
        if exact:
            truth_mean, truth_cov = emulator.moments(emulator_inputs(theta[None], model, conditions))
            observed = truth_mean[0] + rng.multivariate_normal(np.zeros(len(scale[0])), truth_cov[0],
                                                                      size=max(counts))
        else:
            observed = (x[:, :-C] - scale[0]) / scale[1]
        for m in counts:
            if len(observed) < m:
                continue
            hits, widths, right, given, effective = found[m]
            mean_obs = observed[:m].mean(axis=0)
            log_l = np.array([gaussian_log_density(mean_obs - mean, (share + (1 - share) / m) * cov)
                              for mean, cov in moments])
            weights = np.exp(log_l - log_l.max())
            chance = weights.sum(axis=1) / weights.sum()
            w = weights.sum(axis=0) / weights.sum()
            effective.append(1.0 / np.sum(w**2))
            rows = credible_intervals(draws[rng.choice(len(draws), 4000, p=w)])
            hits.append([r["low"] <= t <= r["high"] for r, t in zip(rows, theta)])
            widths.append([r["width_share"] for r in rows])
            right.append(int(np.argmax(chance) == model))
            given.append(float(chance[model]))
    return [(m, len(hits), np.mean(hits, axis=0), np.mean(widths, axis=0), float(np.mean(right)), float(np.mean(given)),
             float(np.min(effective))) for m, (hits, widths, right, given, effective) in found.items()]


def posterior_table(title: str, rows: list, dots: float) -> Table:
    return Table(title, ["observations", "dots in view", "sets", *(p.label for p in PARAMETERS), "mass model right",
                         "mean P(true model)", "fewest effective proposals"],
                 [[m, f"{m * dots:.0f}", n, *(f"{pct(h)} / {pct(w)}" for h, w in zip(hits, widths)), pct(right),
                   f"{given:.2f}", f"{effective:.0f}"] for m, n, hits, widths, right, given, effective in rows])


def study_data(measures, quick: bool) -> tuple:
    """What a study of ``measures`` needs: the emulator's inputs and targets (the posterior's own training films:
    the calibration films left out), the measures' centre and spread over them, the shipped sets and the held-out
    sets (quick: the shipped sets 40-59, no simulation)."""
    theta, models, x, ids = film_arrays(shipped_rows(), measures)
    training = ~np.array([is_calibration_film(i) for i in ids])
    theta, models, x = theta[training], models[training], x[training]
    scale = (x[:, :-C].mean(axis=0), x[:, :-C].std(axis=0))
    u, y = emulator_inputs(theta, models, x[:, -C:]), ((x[:, :-C] - scale[0]) / scale[1]).astype(np.float32)
    shipped = film_sets(shipped_replicates(), measures)
    if quick:
        return u, y, scale, shipped[:40], shipped[40:]
    rows = build_replicates(held_out_folder(False) / "replicates", TEST_GROUPS, 8, workers=2, progress=False,
                            first=TEST_FIRST)
    return u, y, scale, shipped, film_sets(rows, measures)


def learnt_mean(model_of):
    """The function ``(theta, model, x) -> mean (m, k)`` of a set's films from ``model_of(u) -> mean``."""
    return lambda t, model, xs: model_of(emulator_inputs(np.repeat(t[None], len(xs), 0), model, xs[:, -C:]))


def run(quick: bool) -> list:
    from qdots.micrograph.choices import INFER_EXTRA, missing_infer_extra

    if missing_infer_extra():
        return [Note(f"Not run: {INFER_EXTRA}.")]
    import torch

    torch.set_num_threads(1)
    start = time.perf_counter()
    u, y, scale, shipped, held_out = study_data(SUMMARIES, quick)
    if quick:  # short trainings
        sizes, draws, folds, epochs, proposals = (600, None), 1, 2, 30, 2000
    else:
        sizes, draws, folds, epochs, proposals = SIZES, DRAWS, FOLDS, 3000, PROPOSALS
    sets = shipped + held_out
    noise = seed_noise(sets, scale)

    curve = []
    for size in sizes:
        n = len(u) if size is None else size
        errors = []
        for d in range(draws):
            chosen = np.random.default_rng([5621, n, d]).choice(len(u), n, replace=False)
            net = fit(network(y.shape[1], u.shape[1]), squared_error, u[chosen], y[chosen], 100 + d, epochs)

            def mean_of(inputs, net=net):
                with torch.no_grad():
                    return net(torch.as_tensor(inputs)).numpy()

            errors.append(library_error(sets, scale, learnt_mean(mean_of)))
        curve.append((n, np.mean(errors, axis=0)))
    emulator = Emulator(u, y, folds=folds, max_epochs=epochs)
    final_error = library_error(sets, scale, learnt_mean(lambda inputs: emulator.moments(inputs)[0]))
    curve.append((f"{len(u):,} ({folds} folds' ensemble)", final_error))
    share = fitted_share(emulator, shipped, scale)
    dots = float(np.mean([r["complete_dots"] for r in shipped_rows()[:200] if r.get("complete_dots")]))
    modelled = posterior_rows(emulator, held_out, scale, share, COUNTS, proposals)
    exact_taken = posterior_rows(emulator, held_out, scale, 0.0, COUNTS, proposals)
    exact = posterior_rows(emulator, held_out, scale, 0.0, EXACT_COUNTS, EXACT_MORE * proposals, exact=True)
    richer = []
    for label, measures in MEASURE_SETS if not quick else MEASURE_SETS[-1:]:
        mu, my, mscale, mshipped, mheld = study_data(measures, quick)
        memulator = Emulator(mu, my, folds=folds, max_epochs=epochs)
        merror = library_error(mshipped + mheld, mscale, learnt_mean(lambda inputs, e=memulator: e.moments(inputs)[0]))
        ratio_m = float(np.mean(merror / seed_noise(mshipped + mheld, mscale)))
        richer += [(label, ratio_m, row) for row in posterior_rows(memulator, mheld, mscale, 0.0, MEASURE_COUNTS,
                                                                   EXACT_MORE * proposals, exact=True)]
    seconds = time.perf_counter() - start

    learning = Table("The error of the learnt mean against one film's seed noise (summaries in units of their spread "
                     f"over the library; from {len(sets)} replicate sets of 8 films)",
                     ["training films", *SUMMARIES, "error / noise (mean)"],
                     [[n, *(f"{e:.3f}" for e in error), f"{np.mean(error / noise):.2f}"] for n, error in curve]
                     + [["one film's seed noise", *(f"{v:.3f}" for v in noise), "1"],
                        ["8 films' mean", *(f"{v / np.sqrt(8):.3f}" for v in noise), f"{1 / np.sqrt(8):.2f}"]])
    held = f"{len(held_out)} held-out sets" + (" (quick: shipped sets 40-59)" if quick else "")
    ratio = float(np.mean(final_error / noise))
    last, first = modelled[-1], modelled[0]
    return [Headline("qdots infer: several observations of one sample, against the library's own error",
                     f"{seconds:.0f} s",
                     f"library error {ratio:.2f} x one film's noise; 8 observations: widths "
                     f"{pct(last[3].min())}-{pct(last[3].max())} of the prior (1: {pct(first[3].min())}-"
                     f"{pct(first[3].max())}), coverage {pct(last[2].min())}-{pct(last[2].max())}"),
            learning,
            posterior_table(f"Synthetic likelihood, the emulator's error modelled (shared share {share:.2f} of one "
                            f"film's covariance, fitted on the {len(shipped)} shipped sets), {held}: "
                            "90 % coverage / width", modelled, dots),
            posterior_table(f"The same with the emulator taken as exact (no shared error), {held}", exact_taken,
                            dots),
            posterior_table("An exact forward model: observations drawn from the emulator at the held-out sets' "
                            "truths (what the six summaries could tell)", exact, dots),
            Table("An exact forward model of more measures (those the posterior leaves out, as a board reads them): "
                  "90 % coverage / width of the prior",
                  ["measures", "library error / noise", "observations", *(p.label for p in PARAMETERS),
                   "mass model right", "mean P(true model)", "fewest effective proposals"],
                  [[label, f"{ratio_m:.2f}", m, *(f"{pct(h)} / {pct(w)}" for h, w in zip(hits, widths)), pct(right),
                    f"{given:.2f}", f"{effective:.0f}"]
                   for label, ratio_m, (m, _, hits, widths, right, given, effective) in richer]),
            Note(f"Training films: {len(u)} of the shipped library (the calibration films left out, as the posterior "
                 f"does); proposals {proposals} per mass model; {seconds:.0f} s in all on 1 thread.")]


def main(argv: list[str] | None = None) -> int:
    return cli(run, __doc__.splitlines()[0], argv)


if __name__ == "__main__":
    raise SystemExit(main())
