"""Anderson mixing (Anderson 1965; Walker & Ni 2011) of a fixed-point iteration: what the
staged plastic solve (:mod:`solver.stages.plastic`) accelerates its constant-stiffness iteration with."""
from __future__ import annotations

import numpy as np


class Anderson:
    """Anderson acceleration (type II, depth ``m``) of a fixed-point iteration ``x ← G(x)``:
    the next iterate mixes the last ``m`` iterates so that their residuals (``G(x) - x``, or
    what the caller measures instead: :meth:`step`) combine to the least one. The
    constant-stiffness iteration converges linearly, slowly when much of the ground yields;
    mixing turns it into a secant (multisecant) method at the cost of a small least-squares
    problem per iteration."""

    def __init__(self, m: int = 8):
        self.m, self.count = m, 0
        self.last = None  # the last G(x), residual and companion
        self.dG = self.dR = self.dB = None  # (m, n) their differences, the newest at row (count - 1) % m

    def step(self, x: np.ndarray, gx: np.ndarray, companion: np.ndarray | None = None,
             residual: np.ndarray | None = None):
        """The next iterate from ``x`` and ``G(x)``; with a ``companion`` (``K G(x)``: the load ``G``
        solved for) also the same mix of companions: ``K`` times the next iterate, without a product.
        The mix makes the least combination of ``residual`` (default ``G(x) - x``; its size and the
        companion's may differ from the iterate's)."""
        r = gx - x if residual is None else residual
        last, self.last = self.last, (gx, r, companion)
        if last is None or self.m == 0:
            return gx if companion is None else (gx, companion)
        if self.dR is None:
            self.dG, self.dR = np.empty((self.m, gx.size)), np.empty((self.m, r.size))
            if companion is not None:
                self.dB = np.empty((self.m, companion.size))
        row = self.count % self.m
        np.subtract(gx, last[0], out=self.dG[row])
        np.subtract(r, last[1], out=self.dR[row])
        if companion is not None:
            np.subtract(companion, last[2], out=self.dB[row])
        self.count += 1
        k = min(self.count, self.m)
        dR, dG = self.dR[:k], self.dG[:k]
        # the least-squares mix from its normal equations (k ≤ m unknowns; lstsq: the least-norm
        # solution if the differences are dependent)
        gamma = np.linalg.lstsq(dR @ dR.T, dR @ r, rcond=None)[0]
        if companion is None:
            return gx - gamma @ dG
        return gx - gamma @ dG, companion - gamma @ self.dB[:k]
