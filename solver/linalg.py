"""Sparse factorization with a block of "interface" unknowns eliminated last.

The contact problem only needs the stiffness inverse on the interface DOFs,
``(K^-1)[Γ, Γ]``, seen through the normals. Ordering the interface DOFs last (the
rest by METIS nested dissection) makes the trailing block of the LU factors the
Schur complement ``S_Γ = K_ΓΓ - K_ΓI K_II^-1 K_IΓ``, so ``(K^-1)[Γ, Γ] = S_Γ^-1``
costs one factorization plus one small dense triangular solve instead of one
sparse solve per interface DOF.
"""
from __future__ import annotations

import logging

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp
import scipy.sparse.linalg as spla

log = logging.getLogger(__name__)


def nested_dissection(A: sp.spmatrix, groups: np.ndarray | None = None) -> np.ndarray:
    """Fill-reducing ordering of the symmetric pattern of ``A`` (METIS).

    ``groups`` (n,) assigns each unknown to a mesh node; METIS then orders the
    (4x smaller) node graph and the unknowns of a node stay together.
    """
    import pymetis

    A = sp.csr_matrix(A)
    n = A.shape[0]
    if n < 64:
        return np.arange(n)
    if groups is None:
        groups = np.arange(n)
    _, groups = np.unique(groups, return_inverse=True)
    P = sp.csr_matrix((np.ones(n), (groups, np.arange(n))), shape=(groups.max() + 1, n))
    G = (P @ (abs(A) + abs(A.T)) @ P.T).tocsr()
    G.setdiag(0)
    G.eliminate_zeros()
    G.sort_indices()
    node_perm, _ = pymetis.nested_dissection(adjacency=pymetis.CSRAdjacency(G.indptr, G.indices))
    rank = np.empty(len(node_perm), np.int64)
    rank[np.asarray(node_perm)] = np.arange(len(node_perm))
    return np.argsort(rank[groups], kind="stable")


def rotated(K: sp.csr_matrix, T: sp.spmatrix) -> sp.csr_matrix:
    """``Tᵀ K T`` for a symmetric ``K`` and a ``T`` that is the identity but for a few
    unknowns (the interface's): ``K + E`` with ``E = K D + (K D)ᵀ + Dᵀ K D``, ``D = T - I``.

    ``E`` only has the rotated unknowns' rows and columns, so this costs one pass over
    ``K`` and one sum, a third of the two full products (measured 0.028 against 0.085 s
    for the 128k-unknown ground of ``python -m bench.solver``'s finest mesh).
    """
    D = sp.csr_matrix(T - sp.identity(K.shape[0], format="csr"))
    D.eliminate_zeros()
    KD = K @ D
    return sp.csr_matrix(K + (KD + KD.T + D.T @ KD))


class InterfaceFactor:
    """LU factorization of an SPD matrix with the ``last`` unknowns ordered last.

    Parameters
    ----------
    K : (n, n) sparse SPD matrix.
    last : (k,) indices of the interface unknowns.
    groups : (n,) optional mesh node of each unknown (see :func:`nested_dissection`).
    rotation : (n, n) optional sparse orthogonal ``T``: the factor is of ``Tᵀ K T`` (the
        unknowns ``T⁻¹ u``, e.g. normal and tangential components at interface nodes) and
        ``last`` counts in that basis; :meth:`solve` still answers ``K⁻¹ b``. ``T`` must
        mix unknowns of one group only, so the ordering stays that of ``K``.

    The order is the nested dissection of the whole of ``K`` with ``last`` moved to the
    end: the fill equals that of dissecting the rest alone (measured at 166k unknowns:
    14.59M against 14.49M entries in L) without slicing the matrix for it.
    """

    def __init__(self, K: sp.spmatrix, last: np.ndarray, groups: np.ndarray | None = None,
                 rotation: sp.spmatrix | None = None):
        K = sp.csr_matrix(K)
        n = K.shape[0]
        last = np.asarray(last, dtype=np.int64)
        order = nested_dissection(K, groups)
        at_end = np.zeros(n, dtype=bool)
        at_end[last] = True
        self.perm = np.concatenate([order[~at_end[order]], last])
        self.rotation = None if rotation is None else sp.csr_matrix(rotation)
        if self.rotation is not None:
            K = rotated(K, self.rotation)
        Kp = sp.csc_matrix(K[self.perm][:, self.perm])
        # Symmetric pivoting keeps the ordering (K is SPD): U = D L^T.
        self._lu = spla.splu(Kp, permc_spec="NATURAL", diag_pivot_thresh=0.0,
                             options={"SymmetricMode": True})
        self.n, self.k = n, last.size

    def flexibility(self, Bd: np.ndarray) -> np.ndarray:
        """``Bd (K^-1)[last, last] Bd^T`` for a dense (m, k) ``Bd`` acting on ``last``
        (with a ``rotation``: ``K`` is ``Tᵀ K T`` here and ``Bd`` acts in its basis).

        With the interface block trailing, ``(K^-1)[last, last] = S_Γ^-1`` where
        ``S_Γ = U_tt^T D^-1 U_tt`` is the trailing block of the factors, so the
        result is ``Y^T D Y`` with ``Y = U_tt^-T Bd^T``: one dense triangular solve.
        """
        lu, n, k = self._lu, self.n, self.k
        if k == 0:
            return np.zeros((Bd.shape[0], Bd.shape[0]))
        trailing = lu.perm_c[n - k:]
        if not (np.array_equal(lu.perm_c, lu.perm_r)
                and np.array_equal(np.sort(trailing), np.arange(n - k, n))):
            log.warning("SuperLU reordered the interface block; using %d solves", k)
            E = np.zeros((n, k))
            E[np.arange(n - k, n), np.arange(k)] = 1.0
            G = self._lu.solve(E)[n - k:]
            return Bd @ G @ Bd.T
        # SuperLU may postorder the trailing columns: factor position of each interface unknown
        pos = trailing - (n - k)
        U = lu.U.tocsc()[n - k:, n - k:].toarray()
        BdT = np.zeros((k, Bd.shape[0]))
        BdT[pos] = Bd.T
        Y = la.solve_triangular(U, BdT, trans="T", lower=False, check_finite=False)
        return Y.T @ (np.diag(U)[:, None] * Y)

    def solve(self, b: np.ndarray) -> np.ndarray:
        """``K^-1 b`` for a vector or an (n, j) block."""
        b = np.asarray(b, dtype=float)
        T = self.rotation
        if T is not None:
            b = T.T @ b
        x = np.empty_like(b)
        x[self.perm] = self._lu.solve(np.ascontiguousarray(b[self.perm]))
        return x if T is None else T @ x
