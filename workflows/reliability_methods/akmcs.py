"""AK-MCS (Echard, Gayton & Lemaire 2011): a Kriging (Gaussian-process) surrogate of g learned
actively on a Monte Carlo population, and the probability counted on the surrogate.

The population is drawn in the standard normal space; the surrogate is scikit-learn's
``GaussianProcessRegressor`` (constant × anisotropic Matérn 5/2 kernel, hyperparameters by
maximum likelihood, correlation lengths at most 10 standard deviations). Each iteration adds
the population point whose sign is least certain, the minimum of the U criterion U = |μ|/σ, as
one FE call. Learning stops when every point has
U ≥ 2 (each sign wrong with probability below Φ(−2) = 2.3 %); then, if the population is too
small for the estimate (c.o.v. of P over 5 %), it grows and learning goes on. The interval is
the exact binomial one of the population count: the surrogate's own error, once U ≥ 2
everywhere, is taken as negligible. A population of n sees probabilities down to about 10/n:
the largest population (2·10⁶) reaches β ≈ 4.1; smaller probabilities are FORM's or subset
simulation's.
"""
from __future__ import annotations

import math
import warnings
from typing import Callable, Optional

import numpy as np
from scipy import stats

from .limit_state import LimitState
from .result import ReliabilityResult, beta_of

U_STOP = 2.0
TARGET_COV = 0.05
POPULATION = 10_000
MAX_POPULATION = 2_000_000
CHUNK = 100_000
#: Correlation lengths of the surrogate, in standard deviations: the upper bound keeps a few
#: points near the mean from being read as a plane all the way to the tail (an RBF kernel with
#: free lengths fitted 12 points of a parabola with lengths of 371 and 25 and was sure, U > 5,
#: of a probability 10 % off).
LENGTH_BOUNDS = (1e-2, 10.0)


def surrogate(X: np.ndarray, Y: np.ndarray, seed: int):
    """The Gaussian process fitted to the calls (X, Y)."""
    from sklearn.exceptions import ConvergenceWarning
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import ConstantKernel, Matern

    d = X.shape[1]
    kernel = ConstantKernel(1.0, (1e-4, 1e4)) * Matern(np.ones(d), LENGTH_BOUNDS, nu=2.5)
    gp = GaussianProcessRegressor(kernel, alpha=1e-10, normalize_y=True, n_restarts_optimizer=2,
                                  random_state=seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        gp.fit(X, Y)
    return gp


def predict(gp, S: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean and standard deviation of the surrogate on the population, a chunk at a time."""
    mu, sd = np.empty(len(S)), np.empty(len(S))
    for k in range(0, len(S), CHUNK):
        mu[k:k + CHUNK], sd[k:k + CHUNK] = gp.predict(S[k:k + CHUNK], return_std=True)
    return mu, sd


def ak_mcs(g: LimitState, *, seed: int = 0, population: int = POPULATION, max_population: int = MAX_POPULATION,
           target_cov: float = TARGET_COV, initial: Optional[int] = None,
           on_progress: Optional[Callable[[dict], None]] = None) -> ReliabilityResult:
    """P(g < 0) by AK-MCS (see the module's notes)."""
    rng = np.random.default_rng([seed, 3])
    d = g.dimension
    S = rng.standard_normal((population, d))
    n0 = initial or max(12, 2 * d + 2)
    X = S[rng.choice(len(S), n0, replace=False)]
    Y = g(X)
    history: list[dict] = []
    converged, note = False, None
    iteration = 0
    while True:
        iteration += 1
        gp = surrogate(X, Y, seed)
        mu, sd = predict(gp, S)
        with np.errstate(divide="ignore"):
            U = np.abs(mu) / sd
        n, k = len(S), int(np.sum(mu < 0))
        p = k / n
        history.append({"calls": g.calls, "probability": p, "population": n, "min_u": float(U.min()),
                        "stage": f"learning, iteration {iteration}"})
        if on_progress:
            on_progress(history[-1])
        if U.min() >= U_STOP:
            cov = math.sqrt((1 - p) / (p * n)) if p > 0 else float("inf")
            if cov <= target_cov:
                converged = True
                break
            if n >= max_population:
                note = (f"the largest population ({max_population:,}) leaves the estimate's c.o.v. at "
                        f"{cov:.2g}" if p > 0 else f"no failure in the largest population ({max_population:,})")
                converged = p > 0
                break
            grow = max_population if p == 0 else int((1 - p) / (p * target_cov ** 2)) + 1
            size = min(max_population, max(2 * n, grow))
            S = np.vstack([S, rng.standard_normal((size - n, d))])
            continue
        if g.remaining < 1:
            note = f"the budget ended before the surrogate was sure of every sign (min U = {U.min():.2g})"
            break
        best = S[int(np.argmin(U))]
        X = np.vstack([X, best])
        Y = np.append(Y, g(best[None]))
    ci = stats.binomtest(k, n).proportion_ci(0.95, method="exact")
    failed = np.flatnonzero(Y < 0)
    design = X[failed[np.argmin(np.sum(X[failed] ** 2, axis=1))]] if failed.size else None
    return ReliabilityResult(
        method="ak-mcs", probability=p, ci_low=float(ci.low), ci_high=float(ci.high), beta=beta_of(p),
        cov=math.sqrt((1 - p) / (p * n)) if p > 0 else None, design_point=design, calls=g.calls,
        converged=converged, history=history, note=note,
        details={"population": n, "population_failures": k, "iterations": iteration, "min_u": float(U.min()),
                 "kernel": str(gp.kernel_)})
