"""The standard normal space of independent marginals: x_i = F_i⁻¹(Φ(u_i)).

Normal and lognormal variables map in closed form (exact far in the tails, where β 4.7 lives);
uniform and truncated-normal ones through Φ and the inverse CDF of :class:`~workflows.sampling.Distribution`.
Correlated variables (Nataf) are not offered: SPEC §8's distributions are independent.
"""
from __future__ import annotations

import math

import numpy as np
from scipy import stats

from ..sampling import Distribution


def lognormal_parameters(dist: Distribution) -> tuple[float, float]:
    """(μ, σ) of ln X for a lognormal with the given mean and std of X."""
    sigma2 = math.log1p((dist.std / dist.mean) ** 2)
    return math.log(dist.mean) - 0.5 * sigma2, math.sqrt(sigma2)


def to_physical(dist: Distribution, u: np.ndarray) -> np.ndarray:
    """Values of ``dist`` at the standard normal values ``u``."""
    u = np.asarray(u, float)
    if dist.distribution == "normal":
        return dist.mean + dist.std * u
    if dist.distribution == "lognormal":
        mu, sigma = lognormal_parameters(dist)
        return np.exp(mu + sigma * u)
    # Φ(u) for u < 0, 1 - Φ(-u) for u > 0 keeps the digits of the upper tail
    q = np.where(u < 0, stats.norm.cdf(u), 1.0 - stats.norm.sf(u))
    return dist.ppf(np.clip(q, 1e-300, 1.0 - 1e-16))


class StandardSpace:
    """The map from d independent standard normal variables to the study's variables."""

    def __init__(self, distributions: list[Distribution]):
        self.distributions = list(distributions)

    @property
    def dimension(self) -> int:
        return len(self.distributions)

    def to_physical(self, U: np.ndarray) -> np.ndarray:
        """(n, d) standard normal points -> (n, d) values of the variables."""
        U = np.atleast_2d(np.asarray(U, float))
        return np.column_stack([to_physical(d, U[:, j]) for j, d in enumerate(self.distributions)])
