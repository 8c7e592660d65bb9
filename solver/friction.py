"""Coulomb friction on the interface (SPEC §1.2): placeholder until the solver lands."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class FrictionProblem:
    S: np.ndarray
    d: np.ndarray
    g0: float
    w: np.ndarray
    r: np.ndarray
    F2: float
    m: int
    mu: float


def solve_coulomb(fp, theta, *, tol, max_iterations, bolt):
    raise NotImplementedError("coulomb")
