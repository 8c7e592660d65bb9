"""A body's stiffness condensed onto a region of its unknowns: the exact Schur complement's factor.

Where a load is non-zero only on the unknowns ``p`` of a region (the yielding ground's plastic load:
:mod:`solver.stages.region`), the displacement there is ``(K⁻¹ f)_p = S⁻¹ f_p`` with the Schur complement
``S = K_pp - K_pe K_ee⁻¹ K_ep`` of the rest ``e``: the rest of the body, elastic, is eliminated exactly.
With the region ordered last in a Cholesky factorization ``P K Pᵀ = L Lᵀ`` (the rest first, each part by
nested dissection), the factor's trailing block ``L_pp`` is ``S``'s own factor (``K_pp = L_pe L_peᵀ +
L_pp L_ppᵀ``). A solve on the region runs CHOLMOD's supernodal triangular solves over the trailing
supernodes alone (:class:`Tail`: a factor struct over copies of them, the rest of the factor freed): it
sweeps a fraction of the body's factor where the region is a fraction of the body. Products with ``S``
(a few per load step) take ``L_pp`` as a sparse matrix (:func:`trailing_factor`).
"""
from __future__ import annotations

import ctypes

import numpy as np
import scipy.sparse as sp

from .linalg import _DOUBLE, _REAL, Cholesky, _common, _Dense, _dense_p, _factor_p, _failure, _Factor, _int, _lib

for _name in ("cholmod_l_super_lsolve", "cholmod_l_super_ltsolve"):
    getattr(_lib, _name).restype = _int
    getattr(_lib, _name).argtypes = [_factor_p, _dense_p, _dense_p, ctypes.c_void_p]


class Tail:
    """The trailing columns ``c0:`` of a supernodal factor ``L`` (``c0`` the first column of the supernode
    holding column ``start``) as a factor of their own: CHOLMOD's supernodal forward and backward solves
    over those supernodes only. Below a trailing column there are only trailing rows, so ``L[c0:, c0:]`` is
    a Cholesky factor in itself (of the Schur complement of the leading columns).

    The struct's arrays are copies (the integer ones shifted): the factor itself may be freed, and only the
    trailing supernodes' values are kept (at the default mesh a zone's fifth of them)."""

    def __init__(self, chol: Cholesky, start: int):
        f = chol._struct
        ns, sup, pi, px, rows_of, x = chol._supernodes()
        s0 = int(np.searchsorted(sup, start, side="right")) - 1
        self.c0, self.start, n = int(sup[s0]), start, chol.n
        self._arrays = [np.ascontiguousarray(a, dtype=np.int64) for a in (
            sup[s0:] - self.c0, pi[s0:] - pi[s0], px[s0:] - px[s0], rows_of[pi[s0]:] - self.c0)]
        view = _Factor()
        ctypes.pointer(view)[0] = f  # a copy of the struct, then its supernodes moved
        view.n = n - self.c0
        view.nsuper = ns - s0
        view.ssize = int(rows_of.size - pi[s0])
        view.xsize = int(x.size - px[s0])
        view.super, view.pi, view.px, view.s = (a.ctypes.data for a in self._arrays)
        self._values = np.array(x[px[s0]:])
        view.x = self._values.ctypes.data
        view.Perm = view.ColCount = view.IPerm = None
        self._view = view
        self._E = np.zeros(max(int(f.maxesize), 1))

    def solve(self, b: np.ndarray) -> np.ndarray:
        """``(L_pp L_ppᵀ)⁻¹ b`` for ``b`` (k,) on the trailing positions ``start:`` in factor order."""
        m = self._view.n
        X = np.zeros(m)
        X[self.start - self.c0:] = b
        xd = _Dense(m, 1, m, m, X.ctypes.data, None, _REAL, _DOUBLE)
        ed = _Dense(self._E.size, 1, self._E.size, self._E.size, self._E.ctypes.data, None, _REAL, _DOUBLE)
        c = _common()
        for routine in (_lib.cholmod_l_super_lsolve, _lib.cholmod_l_super_ltsolve):
            if not routine(ctypes.byref(self._view), ctypes.byref(xd), ctypes.byref(ed), ctypes.byref(c)):
                raise _failure(c, "region solve")
        return X[self.start - self.c0:]


def trailing_factor(chol: Cholesky, start: int) -> sp.csc_matrix:
    """The columns ``start:`` of a supernodal factor ``L`` (rows ``start:`` too) as a sparse
    lower-triangular (k, k) matrix in factor order: for products with the Schur complement.

    Column ``c`` of supernode ``s`` (its ``j``-th) is the block's column-major column ``j`` from its
    diagonal down: values ``x[px[s] + j (nr + 1) :][: nr - j]`` at the rows ``s[pi[s] + j :]`` (``nr`` the
    supernode's rows), gathered for every trailing column at once."""
    ns, sup, pi, px, rows_of, x = chol._supernodes()
    cols = np.arange(start, chol.n)
    s = np.searchsorted(sup, cols, side="right") - 1  # each column's supernode
    j = cols - sup[s]
    nr = pi[s + 1] - pi[s]
    counts = nr - j
    indptr = np.zeros(cols.size + 1, np.int64)
    np.cumsum(counts, out=indptr[1:])
    within = np.arange(indptr[-1]) - np.repeat(indptr[:-1], counts)  # position down each column
    data = x[np.repeat(px[s] + j * (nr + 1), counts) + within]
    rows = rows_of[np.repeat(pi[s] + j, counts) + within] - start
    k = chol.n - start
    return sp.csc_matrix((data, rows, indptr), shape=(k, k))


class RegionSchur:
    """``K`` (n, n) SPD condensed onto its unknowns ``inside`` (a boolean (n,) mask, not empty), with
    ``order`` a fill-reducing ordering of all unknowns (:func:`~solver.fe.linalg.nested_dissection`):
    :meth:`solve` with the Schur complement ``S`` on them and :meth:`product` by it.

    Attribute: ``dofs``, the region's unknowns (ascending)."""

    def __init__(self, K: sp.spmatrix, order: np.ndarray, inside: np.ndarray):
        inside = np.asarray(inside, bool)
        n = K.shape[0]
        order = np.asarray(order)
        perm = np.concatenate([order[~inside[order]], order[inside[order]]])
        start = n - int(inside.sum())
        chol = Cholesky(K, perm, postorder=False)
        if not np.array_equal(chol.perm, perm):
            raise RuntimeError("CHOLMOD did not keep the region's unknowns last")
        self._tail = Tail(chol, start)
        self._L = trailing_factor(chol, start)
        self.dofs = np.flatnonzero(inside)
        #: the position in ``dofs`` of each trailing factor position's unknown
        self._at = np.searchsorted(self.dofs, perm[start:])

    def solve(self, b: np.ndarray) -> np.ndarray:
        """``S⁻¹ b`` for ``b`` on the region's unknowns (``dofs``' order)."""
        x = self._tail.solve(b[self._at])
        out = np.empty_like(x)
        out[self._at] = x
        return out

    def product(self, x: np.ndarray) -> np.ndarray:
        """``S x`` for ``x`` on the region's unknowns."""
        y = self._L @ (self._L.T @ x[self._at])  # (the transpose a CSR view of the same arrays)
        out = np.empty_like(y)
        out[self._at] = y
        return out
