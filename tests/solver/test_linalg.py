"""The interface-last factorization against dense linear algebra."""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from solver.linalg import InterfaceFactor


def laplacian_2d(n: int) -> sp.csr_matrix:
    T = sp.diags([-1, 2.1, -1], [-1, 0, 1], shape=(n, n))
    return (sp.kron(sp.eye(n), T) + sp.kron(T, sp.eye(n))).tocsr()


def test_flexibility_and_solve_match_dense_inverse():
    K = laplacian_2d(14)  # 196 unknowns, SPD
    rng = np.random.default_rng(0)
    last = np.sort(rng.choice(K.shape[0], 23, replace=False))
    groups = np.arange(K.shape[0]) // 2
    f = InterfaceFactor(K, last, groups)
    Kinv = np.linalg.inv(K.toarray())
    Bd = rng.standard_normal((9, last.size))
    np.testing.assert_allclose(f.flexibility(Bd), Bd @ Kinv[np.ix_(last, last)] @ Bd.T, rtol=1e-10, atol=1e-12)
    b = rng.standard_normal(K.shape[0])
    np.testing.assert_allclose(f.solve(b), Kinv @ b, rtol=1e-10, atol=1e-12)
