"""Sampled sweeps (SPEC §8): the values of each varied parameter drawn from a distribution by
scrambled Sobol' points, a Latin hypercube or plain Monte Carlo.

``scipy.stats.qmc`` gives n points in the unit hypercube (one dimension per varied parameter, in
the order of ``vary``); each coordinate goes through the inverse CDF of its parameter's
distribution (``scipy.stats``). The same seed gives the same points, so the same cases and ids.
"""
from __future__ import annotations

import math
from typing import Literal, Optional

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

#: Largest number of samples a sampled sweep may ask for.
MAX_SAMPLES = 4096
SAMPLED_MODES = ("sobol", "lhs", "random")


class Distribution(BaseModel):
    """The distribution of one varied parameter of a sampled sweep."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    distribution: Literal["uniform", "normal", "lognormal", "truncated-normal"]
    low: Optional[float] = Field(None, allow_inf_nan=False, description="lower bound (uniform, truncated-normal)")
    high: Optional[float] = Field(None, allow_inf_nan=False, description="upper bound (uniform, truncated-normal)")
    mean: Optional[float] = Field(None, allow_inf_nan=False, description="mean of the variable itself")
    std: Optional[float] = Field(None, allow_inf_nan=False, description="standard deviation of the variable itself")

    @model_validator(mode="after")
    def _complete(self) -> "Distribution":
        need = {"uniform": ("low", "high"), "normal": ("mean", "std"), "lognormal": ("mean", "std"),
                "truncated-normal": ("mean", "std", "low", "high")}[self.distribution]
        given = {k for k in ("low", "high", "mean", "std") if getattr(self, k) is not None}
        for name in need:
            if name not in given:
                raise ValueError(f"{name}: a {self.distribution} distribution needs {', '.join(need)}")
        for name in sorted(given - set(need)):
            raise ValueError(f"{name}: a {self.distribution} distribution takes only {', '.join(need)}")
        if "low" in need and not self.low < self.high:
            raise ValueError(f"high: must exceed low ({self.low} >= {self.high})")
        if "std" in need and not self.std > 0:
            raise ValueError(f"std: must be positive ({self.std})")
        if self.distribution == "lognormal" and not self.mean > 0:
            raise ValueError(f"mean: a lognormal variable is positive; its mean must be too ({self.mean})")
        return self

    def ppf(self, q: np.ndarray) -> np.ndarray:
        """Values at probabilities ``q`` (the inverse CDF)."""
        from scipy import stats

        if self.distribution == "uniform":
            return self.low + (self.high - self.low) * q
        if self.distribution == "normal":
            return stats.norm.ppf(q, loc=self.mean, scale=self.std)
        if self.distribution == "lognormal":  # mean and std of the variable -> the underlying normal's
            sigma2 = math.log1p((self.std / self.mean) ** 2)
            return stats.lognorm.ppf(q, s=math.sqrt(sigma2), scale=self.mean * math.exp(-0.5 * sigma2))
        a, b = (self.low - self.mean) / self.std, (self.high - self.mean) / self.std
        return stats.truncnorm.ppf(q, a, b, loc=self.mean, scale=self.std)


def unit_points(mode: str, samples: int, dimensions: int, seed: int) -> np.ndarray:
    """(samples, dimensions) points in the open unit hypercube."""
    from scipy.stats import qmc

    if mode == "sobol":
        points = qmc.Sobol(dimensions, scramble=True, seed=seed).random(samples)
    elif mode == "lhs":
        points = qmc.LatinHypercube(dimensions, seed=seed).random(samples)
    else:
        points = np.random.default_rng(seed).random((samples, dimensions))
    return np.clip(points, 1e-12, 1 - 1e-12)  # the inverse CDF of an unbounded law is finite inside


def sample_errors(mode: str, samples: Optional[int], vary: dict) -> list[tuple[str, str]]:
    """Problems of a sampled sweep's settings: ``(field, reason)``."""
    errors = []
    if samples is None:
        errors.append(("samples", f"a {mode} sweep needs the number of samples"))
    elif not 1 <= samples <= MAX_SAMPLES:
        errors.append(("samples", f"{samples} is outside [1, {MAX_SAMPLES}]"))
    elif mode == "sobol" and samples & (samples - 1):
        errors.append(("samples", f"{samples} is not a power of 2 (Sobol' points keep their balance only then)"))
    for path, entry in vary.items():
        if not isinstance(entry, Distribution):
            errors.append((f"vary.{path}", f"a {mode} sweep takes a distribution "
                                           "({'distribution': 'uniform', 'low': ..., 'high': ...}), not a list"))
    return errors


def sampled_values(mode: str, samples: int, seed: int, vary: dict) -> dict[str, list[float]]:
    """The values of each varied parameter, one per sample (the zip of the sampled cases)."""
    paths = list(vary)
    q = unit_points(mode, samples, len(paths), seed)
    return {path: [float(v) for v in vary[path].ppf(q[:, j])] for j, path in enumerate(paths)}
