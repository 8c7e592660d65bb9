"""Sparse factorization with a block of "interface" unknowns eliminated last.

The contact problem only needs the stiffness inverse on the interface DOFs,
``G = (K^-1)[Γ, Γ]``. Ordering the interface DOFs last (the rest by METIS nested
dissection) makes the trailing block of the LU factors the Schur complement
``S_Γ = K_ΓΓ - K_ΓI K_II^-1 K_IΓ``, so ``G = S_Γ^-1`` costs one factorization
plus a small dense inverse instead of one solve per interface DOF.
"""
from __future__ import annotations

import logging

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp
import scipy.sparse.linalg as spla

log = logging.getLogger(__name__)


def nested_dissection(A: sp.spmatrix) -> np.ndarray:
    """Fill-reducing ordering of the symmetric pattern of ``A`` (METIS)."""
    import pymetis

    A = sp.csr_matrix(A)
    n = A.shape[0]
    if n < 64:
        return np.arange(n)
    G = (A + A.T).tocsr()
    G.setdiag(0)
    G.eliminate_zeros()
    G.sort_indices()
    perm, _ = pymetis.nested_dissection(adjacency=pymetis.CSRAdjacency(G.indptr, G.indices))
    return np.asarray(perm, dtype=np.int64)


class InterfaceFactor:
    """LU factorization of an SPD matrix with the ``last`` unknowns ordered last.

    Parameters
    ----------
    K : (n, n) sparse SPD matrix.
    last : (k,) indices of the interface unknowns.

    Attributes
    ----------
    G : (k, k) dense ``(K^-1)[last][:, last]``.
    """

    def __init__(self, K: sp.spmatrix, last: np.ndarray):
        K = sp.csr_matrix(K)
        n = K.shape[0]
        last = np.asarray(last, dtype=np.int64)
        rest = np.setdiff1d(np.arange(n), last)
        inner = rest[nested_dissection(K[rest][:, rest])]
        self.perm = np.concatenate([inner, last])
        Kp = sp.csc_matrix(K[self.perm][:, self.perm])
        self._lu = spla.splu(Kp, permc_spec="NATURAL", diag_pivot_thresh=0.0,
                             options={"SymmetricMode": True})
        self.n, self.k = n, last.size
        self.G = self._trailing_inverse()

    def _trailing_inverse(self) -> np.ndarray:
        lu, n, k = self._lu, self.n, self.k
        if k == 0:
            return np.zeros((0, 0))
        ok = (np.array_equal(lu.perm_c, lu.perm_r)
              and np.array_equal(np.sort(lu.perm_c[n - k:]), np.arange(n - k, n)))
        if ok:
            # SuperLU may postorder the trailing columns; map them back.
            pos = lu.perm_c[n - k:] - (n - k)
            L = lu.L.tocsc()[n - k:, n - k:].toarray()
            U = lu.U.tocsc()[n - k:, n - k:].toarray()
            S = L @ U  # Schur complement in factor order
            Ginv = la.inv(S)
            return Ginv[np.ix_(pos, pos)]
        log.warning("SuperLU reordered the interface block; computing G by %d solves", k)
        E = np.zeros((n, k))
        E[np.arange(n - k, n), np.arange(k)] = 1.0
        return self._lu.solve(E)[n - k:]

    def solve(self, b: np.ndarray) -> np.ndarray:
        """``K^-1 b`` for a vector or an (n, j) block."""
        b = np.asarray(b, dtype=float)
        x = np.empty_like(b)
        x[self.perm] = self._lu.solve(np.ascontiguousarray(b[self.perm]))
        return x
