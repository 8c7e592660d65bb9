"""What a reliability algorithm returns, in the standard normal space (the driver names it)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Optional

import numpy as np
from scipy import stats


def beta_of(probability: float) -> Optional[float]:
    """β = −Φ⁻¹(P); None where P is 0 or 1."""
    if not 0.0 < probability < 1.0:
        return None
    return float(-stats.norm.ppf(probability))


def lognormal_interval(probability: float, cov: float, z: float = 1.959964) -> tuple[float, float]:
    """95 % interval of an estimate with coefficient of variation ``cov``, taken lognormal
    (positive, and skewed as small-probability estimators are)."""
    if probability <= 0.0 or not math.isfinite(cov):
        return 0.0, 1.0 if probability <= 0.0 else probability
    s = math.sqrt(math.log1p(cov ** 2))
    return probability * math.exp(-z * s), min(1.0, probability * math.exp(z * s))


@dataclass
class ReliabilityResult:
    """An estimate of P(g < 0).

    ``design_point``: the point of the standard space the result names (FORM's design point,
    or the failed sample of highest density), None if none was found; ``importance``: α²
    of each variable (its direction cosine squared); ``history``: the estimate against calls.
    """

    method: str
    probability: float
    ci_low: float
    ci_high: float
    beta: Optional[float]
    cov: Optional[float]
    design_point: Optional[np.ndarray]
    calls: int
    converged: bool
    history: list[dict[str, Any]] = field(default_factory=list)
    details: dict[str, Any] = field(default_factory=dict)
    note: Optional[str] = None

    @property
    def importance(self) -> Optional[np.ndarray]:
        u = self.design_point
        if u is None or not np.any(u):
            return None
        return u ** 2 / float(u @ u)
