"""The equality-constrained system of one active set (``solver.contact.bolt.solve_on_set``)."""
from __future__ import annotations

import numpy as np
import pytest

from solver.contact.bolt import DualProblem, solve_on_set


def _bordered(dual: DualProblem, active: np.ndarray) -> np.ndarray:
    """The system solved as a whole, densely: gap = 0 on the set, λ = 0 off it, balance."""
    idx = np.flatnonzero(active)
    WSW = (dual.w[:, None] * dual.S) * dual.w[None, :]
    n = idx.size
    A = np.zeros((n + 1, n + 1))
    A[:n, :n] = WSW[np.ix_(idx, idx)]
    A[:n, n] = A[n, :n] = (dual.w * dual.nu2)[idx]
    x = np.linalg.solve(A, np.r_[(dual.w * (dual.d - dual.g0))[idx], -dual.F2])
    lam = np.zeros(dual.m)
    lam[idx] = x[:n]
    return lam


@pytest.mark.parametrize("singular", [False, True])
def test_solve_on_set_is_the_bordered_system(singular):
    """By the Cholesky factor of the set's flexibility block (SPD), and, when that block is
    singular but the balance row makes the system regular, by the whole bordered system."""
    rng = np.random.default_rng(7)
    m = 6
    M = rng.standard_normal((m, m))
    S = M @ M.T + m * np.eye(m)
    if singular:
        S[:, 1] = S[:, 0]  # nodes 0 and 1 answer alike: the block is singular
        S[1, :] = S[0, :]
    dual = DualProblem(S=S, d=rng.standard_normal(m), g0=np.zeros(m), w=rng.uniform(0.5, 1.5, m),
                       nu2=np.r_[1.0, -1.0, rng.uniform(-1, 1, m - 2)], F2=-3.0)
    active = np.array([True, True, True, False, True, True])
    lam = solve_on_set(dual, active)
    np.testing.assert_allclose(lam, _bordered(dual, active), rtol=1e-9, atol=1e-12)
    assert np.all(lam[~active] == 0.0)
    assert (dual.w * dual.nu2) @ lam == pytest.approx(-dual.F2)  # the lining's balance
