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


def _ranges(starts: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """The concatenated ``arange(start, start + count)`` of each pair."""
    ends = np.cumsum(counts)
    return np.repeat(starts - (ends - counts), counts) + np.arange(int(ends[-1]) if ends.size else 0)


class _SubFactor:
    """The supernodes ``keep`` (a mask closed under the elimination tree: each one's rows are columns of kept
    supernodes) of a supernodal factor ``L`` as a factor of their own, their columns numbered in order
    (``columns``: their positions in ``L``): CHOLMOD's supernodal forward and backward solves over them alone.
    The struct's arrays are copies (the integer ones renumbered), so the factor itself may be freed."""

    def __init__(self, chol: Cholesky, keep: np.ndarray):
        f = chol._struct
        ns, sup, pi, px, rows_of, x = chol._supernodes()
        S = np.flatnonzero(keep)
        ncol, nr = np.diff(sup)[S], np.diff(pi)[S]
        kept = np.repeat(keep, np.diff(sup))
        self.columns = np.flatnonzero(kept)
        compact = np.cumsum(kept) - 1
        rows = rows_of[_ranges(pi[S], nr)]
        if not kept[rows].all():
            raise RuntimeError("the supernodes kept are not closed under the elimination tree")
        self._arrays = [np.ascontiguousarray(a, dtype=np.int64) for a in (
            np.r_[0, np.cumsum(ncol)], np.r_[0, np.cumsum(nr)], np.r_[0, np.cumsum(nr * ncol)], compact[rows])]
        self._values = np.ascontiguousarray(x[_ranges(px[S], nr * ncol)])
        view = _Factor()
        ctypes.pointer(view)[0] = f  # a copy of the struct, then its supernodes replaced
        view.n, view.nsuper = self.columns.size, S.size
        view.ssize, view.xsize = int(rows.size), int(self._values.size)
        view.super, view.pi, view.px, view.s = (a.ctypes.data for a in self._arrays)
        view.x = self._values.ctypes.data
        view.Perm = view.ColCount = view.IPerm = None
        self._view, self.n = view, self.columns.size
        self._E = np.zeros(max(int(f.maxesize), 1))

    def _sweep(self, X: np.ndarray, routines) -> np.ndarray:
        m = self.n
        xd = _Dense(m, 1, m, m, X.ctypes.data, None, _REAL, _DOUBLE)
        ed = _Dense(self._E.size, 1, self._E.size, self._E.size, self._E.ctypes.data, None, _REAL, _DOUBLE)
        c = _common()
        for routine in routines:
            if not routine(ctypes.byref(self._view), ctypes.byref(xd), ctypes.byref(ed), ctypes.byref(c)):
                raise _failure(c, "partial solve")
        return X

    def lsolve(self, b: np.ndarray) -> np.ndarray:
        """``L⁻¹ b`` over the kept columns (``b`` on them, in order)."""
        return self._sweep(np.array(b, dtype=float), (_lib.cholmod_l_super_lsolve,))

    def ltsolve(self, y: np.ndarray) -> np.ndarray:
        """``L⁻ᵀ y`` over the kept columns."""
        return self._sweep(np.array(y, dtype=float), (_lib.cholmod_l_super_ltsolve,))

    def solve(self, b: np.ndarray) -> np.ndarray:
        return self._sweep(np.array(b, dtype=float), (_lib.cholmod_l_super_lsolve, _lib.cholmod_l_super_ltsolve))


class Tail:
    """The trailing columns ``c0:`` of a supernodal factor ``L`` (``c0`` the first column of the supernode
    holding column ``start``) as a factor of their own (:class:`_SubFactor`). Below a trailing column there are
    only trailing rows, so ``L[c0:, c0:]`` is a Cholesky factor in itself (of the Schur complement of the
    leading columns); only the trailing supernodes' values are kept (at the default mesh a zone's fifth of them)."""

    def __init__(self, chol: Cholesky, start: int):
        ns, sup = chol._supernodes()[:2]
        s0 = int(np.searchsorted(sup, start, side="right")) - 1
        self._sub = _SubFactor(chol, np.arange(ns) >= s0)
        self.c0, self.start = int(sup[s0]), start

    def solve(self, b: np.ndarray) -> np.ndarray:
        """``(L_pp L_ppᵀ)⁻¹ b`` for ``b`` (k,) on the trailing positions ``start:`` in factor order."""
        X = np.zeros(self._sub.n)
        X[self.start - self.c0:] = b
        return self._sub.solve(X)[self.start - self.c0:]


def _etree(chol: Cholesky) -> tuple[np.ndarray, np.ndarray]:
    """Each column's supernode and each supernode's parent in the elimination tree (-1 at a root), found once."""
    if getattr(chol, "_etree", None) is None:
        ns, sup, pi, _, rows_of, _ = chol._supernodes()
        ncol, nr = np.diff(sup), np.diff(pi)
        of = np.repeat(np.arange(ns), ncol)
        parent = np.full(ns, -1, np.int64)
        has = nr > ncol
        parent[has] = of[rows_of[pi[:-1][has] + ncol[has]]]
        chol._etree = (of, parent)
    return chol._etree


class Reach:
    """Solves of a factorized ``K`` (:class:`~solver.fe.linalg.InterfaceFactor`) for loads on some of its
    unknowns (and the interface's: they are the factor's last), read there: a load on them moves the forward
    solve only along the elimination tree's ancestors of their columns, and their displacements need the
    backward solve only there, so both sweep those supernodes alone (:class:`_SubFactor`; at the default mesh
    a yielding zone's reach is about 40 % of the factor). Vectors are on the reached columns, in factor order
    (``columns``): :meth:`forward` takes a load on ``unknowns``, :meth:`backward` gives every reached column's
    value, :meth:`at` reads ``unknowns``' among them; the interface's ``k`` are the last."""

    def __init__(self, factor, unknowns: np.ndarray):
        chol = factor.cholesky
        of, parent = _etree(chol)
        keep = np.zeros(parent.size, bool)
        frontier = np.unique(of[factor.positions(unknowns)])
        while frontier.size:
            keep[frontier] = True
            frontier = np.unique(parent[frontier])
            frontier = frontier[frontier >= 0]
            frontier = frontier[~keep[frontier]]
        self._sub = _SubFactor(chol, keep)
        self.columns = self._sub.columns
        local = np.full(chol.n, -1, np.int64)
        local[self.columns] = np.arange(self.columns.size)
        self._at = local[factor.positions(unknowns)]

    def forward(self, b: np.ndarray) -> np.ndarray:
        """``L⁻¹ P b`` on the reached columns for ``b`` on ``unknowns`` (zero elsewhere: it is zero beyond them)."""
        X = np.zeros(self.columns.size)
        X[self._at] = b
        return self._sub.lsolve(X)

    def backward(self, y: np.ndarray) -> np.ndarray:
        """``L⁻ᵀ y`` on the reached columns: there, ``K⁻¹ b`` of the load whose forward solve gave ``y``."""
        return self._sub.ltsolve(y)

    def at(self, v: np.ndarray) -> np.ndarray:
        """``unknowns``' values of a vector on the reached columns."""
        return v[self._at]


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
