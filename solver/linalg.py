"""Sparse Cholesky factorization with a block of "interface" unknowns eliminated last.

The contact problem only needs the stiffness inverse on the interface DOFs,
``(K^-1)[Γ, Γ]``, seen through the normals. Ordering the interface DOFs last (the rest
by nested dissection) makes the trailing block ``L_ΓΓ`` of the Cholesky factor
``P K Pᵀ = L Lᵀ`` the factor of the Schur complement ``S_Γ = K_ΓΓ - K_ΓI K_II^-1 K_IΓ``,
so ``(K^-1)[Γ, Γ] = S_Γ^-1 = L_ΓΓ^-ᵀ L_ΓΓ^-1`` costs one factorization plus one small
dense inversion instead of one sparse solve per interface DOF.

It also splits a solve in two halves around the interface, so a contact case costs the
same triangular solves as one elastic solve (:meth:`InterfaceFactor.forward`,
:meth:`~InterfaceFactor.interface`, :meth:`~InterfaceFactor.lift`,
:meth:`~InterfaceFactor.backward`): for ``x = K⁻¹(f - g)`` with ``g`` on Γ,
``y = L⁻¹ P f`` gives ``x_Γ`` of ``K⁻¹f`` from ``L_ΓΓ`` alone, and
``x = Pᵀ L⁻ᵀ (y - [0; L_ΓΓ⁻¹ g_Γ])``.

The factorization is CHOLMOD's supernodal Cholesky (Chen, Davis, Hager & Rajamanickam,
ACM TOMS 35(3), 2008), as bundled with cvxopt. cvxopt hands out the factor only as a
whole sparse copy (0.2 s at 128k unknowns, as long as the factorization); the trailing
block is read in place from CHOLMOD's public ``cholmod_factor`` struct instead
(:func:`_trailing_block`), checked against ``cholmod.diag`` on every factorization.
"""
from __future__ import annotations

import ctypes

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp
from cvxopt import cholmod
from cvxopt import matrix as cvx_matrix
from cvxopt import spmatrix as cvx_spmatrix

from .contact import SolverError

# Supernodal LLᵀ; the permutation given (no ordering of CHOLMOD's own on top).
cholmod.options.update({"supernodal": 2, "nmethods": 1, "postorder": True})


class FactorizationError(SolverError):
    """A stiffness matrix that is not positive definite (a body not held): a solver failure
    like any other, recorded with the case and reported by the CLI and the service."""


def _cvx_lower(A: sp.spmatrix) -> cvx_spmatrix:
    """The lower triangle of a symmetric ``A`` as a cvxopt sparse matrix."""
    L = sp.tril(A, format="csc")
    L.sort_indices()
    n = A.shape[0]
    cols = np.repeat(np.arange(n, dtype=np.int64), np.diff(L.indptr))
    return cvx_spmatrix(cvx_matrix(np.asarray(L.data, dtype=float)), cvx_matrix(L.indices.astype(np.int64)),
                        cvx_matrix(cols), (n, n))


def nested_dissection(mesh, node_of_unknown: np.ndarray) -> np.ndarray:
    """Fill-reducing ordering of a quadratic-triangle body's unknowns (METIS nested
    dissection of the mesh's vertex graph).

    ``mesh`` is a scikit-fem ``MeshTri2`` (vertices ``0..nv-1``, the node of edge f is
    ``nv + f``); ``node_of_unknown`` (n,) the node of each unknown. METIS orders the
    vertex graph (a quarter of the nodes, a ninth of the node graph's edges); an edge node
    goes just before the earlier of its two vertices, so a separator's edge nodes stay in
    the separator and a subdomain's in the subdomain, and a node's unknowns stay together.
    Measured at 128k unknowns (``python -m bench.ordering``) against METIS on the whole
    node graph and against AMD: 0.07 s to find against 0.45 and 0.10 s, and the smallest
    factor of the three.
    """
    import pymetis

    a, b = mesh.facets
    nv = int(mesh.t.max()) + 1
    G = sp.csr_matrix((np.ones(2 * a.size), (np.r_[a, b], np.r_[b, a])), shape=(nv, nv))
    G.sort_indices()
    vertex_order, _ = pymetis.nested_dissection(adjacency=pymetis.CSRAdjacency(G.indptr, G.indices))
    vertex_rank = np.empty(nv)
    vertex_rank[np.asarray(vertex_order)] = np.arange(nv)
    rank = np.r_[vertex_rank, np.minimum(vertex_rank[a], vertex_rank[b]) - 0.5]
    return np.lexsort((np.arange(node_of_unknown.size), rank[node_of_unknown]))


def rotated(K: sp.csr_matrix, T: sp.spmatrix) -> sp.csr_matrix:
    """``Tᵀ K T`` for a symmetric ``K`` and a ``T`` that is the identity but for a few
    unknowns (the interface's): ``K + E`` with ``E = K D + (K D)ᵀ + Dᵀ K D``, ``D = T - I``.

    ``E`` only has the rotated unknowns' rows and columns, so this costs one pass over
    ``K`` and one sum, a third of the two full products (measured 0.028 against 0.085 s
    for the 128k-unknown ground of ``python -m bench.solver``'s finest mesh).
    """
    D = sp.csr_matrix(T - sp.identity(K.shape[0], format="csr"))
    D.eliminate_zeros()
    R = np.flatnonzero(np.diff(D.indptr))  # the rotated unknowns
    KD = sp.csr_matrix(K[R].T @ D[R])  # K D = K[:, R] D[R] = K[R]ᵀ D[R] for a symmetric K
    return sp.csr_matrix(K + (KD + KD.T + D.T @ KD))


class _CholmodFactor(ctypes.Structure):
    """``cholmod_factor`` (cholmod.h, unchanged from SuiteSparse 4 to 7)."""

    _fields_ = [(name, ctypes.c_size_t) for name in ("n", "minor")] \
        + [(name, ctypes.c_void_p) for name in ("Perm", "ColCount", "IPerm")] \
        + [("nzmax", ctypes.c_size_t)] \
        + [(name, ctypes.c_void_p) for name in ("p", "i", "x", "z", "nz", "next", "prev")] \
        + [(name, ctypes.c_size_t) for name in ("nsuper", "ssize", "xsize", "maxcsize", "maxesize")] \
        + [(name, ctypes.c_void_p) for name in ("super", "pi", "px", "s")] \
        + [(name, ctypes.c_int) for name in ("ordering", "is_ll", "is_super", "is_monotonic",
                                              "itype", "xtype", "dtype", "useGPU")]


_CHOLMOD_LONG, _CHOLMOD_REAL, _CHOLMOD_DOUBLE = 2, 1, 0  # cholmod.h
_capsule_pointer = ctypes.pythonapi.PyCapsule_GetPointer
_capsule_pointer.restype, _capsule_pointer.argtypes = ctypes.c_void_p, [ctypes.py_object, ctypes.c_char_p]
_capsule_name = ctypes.pythonapi.PyCapsule_GetName
_capsule_name.restype, _capsule_name.argtypes = ctypes.c_char_p, [ctypes.py_object]


def _view(address: int, size: int, ctype) -> np.ndarray:
    return np.ctypeslib.as_array(ctypes.cast(address, ctypes.POINTER(ctype)), (size,))


def _factor_struct(F, n: int) -> _CholmodFactor:
    f = _CholmodFactor.from_address(_capsule_pointer(F, _capsule_name(F)))
    if not (f.n == n and f.is_super and f.is_ll and f.itype == _CHOLMOD_LONG and f.xtype == _CHOLMOD_REAL
            and f.dtype == _CHOLMOD_DOUBLE):
        raise RuntimeError("unexpected CHOLMOD factor layout (cvxopt's CHOLMOD changed)")
    return f


def _factorize(A: cvx_spmatrix, perm: np.ndarray, postorder: bool):
    """CHOLMOD's supernodal ``P A Pᵀ = L Lᵀ`` of the lower triangle ``A``, ``P`` from ``perm``."""
    cholmod.options["postorder"] = postorder
    try:
        F = cholmod.symbolic(A, p=cvx_matrix(perm), uplo="L")
        cholmod.numeric(A, F)
    except ArithmeticError as exc:
        raise FactorizationError(f"the stiffness matrix is not positive definite ({exc})") from None
    finally:
        cholmod.options["postorder"] = True
    return F


def _permutation(F, n: int) -> np.ndarray:
    """CHOLMOD's final permutation: the unknown at each factor position."""
    return _view(_factor_struct(F, n).Perm, n, ctypes.c_int64).copy()


def _trailing_block(F, n: int, k: int) -> np.ndarray:
    """The dense lower trailing ``k x k`` block of a supernodal ``L``, copied out of the factor.

    Each supernode stores its columns ``super[s]:super[s+1]`` as a dense column-major
    block of the rows ``s[pi[s]:pi[s+1]]`` at ``x[px[s]:]``; the supernodes covering the
    last k columns hold ``L_ΓΓ``.
    """
    f = _factor_struct(F, n)
    it = ctypes.c_int64
    ns = f.nsuper
    sup, pi, px = (_view(a, ns + 1, it) for a in (f.super, f.pi, f.px))
    rows_of, x = _view(f.s, f.ssize, it), _view(f.x, f.xsize, ctypes.c_double)
    start = n - k
    s = ns - 1
    c0, nr = int(sup[s]), int(pi[s + 1] - pi[s])
    if c0 <= start and nr == n - c0:
        # one dense supernode holds the trailing columns (as for any connected interface)
        Ltt = x[px[s]: px[s] + nr * nr].reshape(nr, nr).T[start - c0:, start - c0:].copy()
    else:
        Ltt = np.zeros((k, k))
        while s >= 0 and sup[s + 1] > start:
            c0, c1 = int(sup[s]), int(sup[s + 1])
            nr = int(pi[s + 1] - pi[s])
            block = x[px[s]: px[s] + nr * (c1 - c0)].reshape(c1 - c0, nr).T
            rows = rows_of[pi[s]: pi[s + 1]]
            r, c = rows >= start, np.arange(c0, c1) >= start
            Ltt[np.ix_(rows[r] - start, np.arange(c0, c1)[c] - start)] = block[np.ix_(r, c)]
            s -= 1
    if k and not np.array_equal(np.diag(Ltt), np.asarray(cholmod.diag(F)).ravel()[start:]):
        raise RuntimeError("the CHOLMOD factor read in place disagrees with cholmod.diag")
    return np.tril(Ltt)


class InterfaceFactor:
    """Cholesky factorization of an SPD matrix with the ``last`` unknowns ordered last.

    Parameters
    ----------
    K : (n, n) sparse SPD matrix.
    last : (k,) indices of the interface unknowns.
    order : (n,) optional fill-reducing ordering of the unknowns (:func:`nested_dissection`);
        the factor uses it with ``last`` moved to the end. Default: as numbered.
    rotation : (n, n) optional sparse orthogonal ``T``: the factor is of ``Tᵀ K T`` (the
        unknowns ``T⁻¹ u``, e.g. normal and tangential components at interface nodes) and
        ``last`` counts in that basis; the solves still answer ``K⁻¹ b``. ``T`` must mix
        unknowns of one group only, so the ordering stays that of ``K``.

    Raises :class:`FactorizationError` if the matrix is not positive definite.
    """

    def __init__(self, K: sp.spmatrix, last: np.ndarray, order: np.ndarray | None = None,
                 rotation: sp.spmatrix | None = None):
        K = sp.csr_matrix(K)
        n = K.shape[0]
        self.last = np.asarray(last, dtype=np.int64)
        order = np.arange(n) if order is None else np.asarray(order)
        at_end = np.zeros(n, dtype=bool)
        at_end[self.last] = True
        perm = np.concatenate([order[~at_end[order]], self.last])
        self.rotation = None if rotation is None else sp.csr_matrix(rotation)
        if self.rotation is not None:
            K = rotated(K, self.rotation)
        A = _cvx_lower(K)
        self.n, self.k = n, self.last.size
        # CHOLMOD postorders the elimination tree (4 % less factorization time at 128k
        # unknowns): a permutation of ours that keeps a connected interface block trailing.
        # An interface in several unconnected parts could be moved apart: then ours as given.
        for postorder in (True, False):
            self._F = _factorize(A, perm, postorder)
            self._perm = _permutation(self._F, n)
            if np.array_equal(np.sort(self._perm[n - self.k:]), np.sort(self.last)):
                break
        else:
            raise RuntimeError("CHOLMOD did not keep the interface unknowns last")
        self._Ltt = _trailing_block(self._F, n, self.k)
        where = np.empty(n, np.int64)
        where[self._perm[n - self.k:]] = np.arange(self.k)
        #: trailing-block position of each of ``last``
        self._pos = where[self.last]

    # -- the interface -----------------------------------------------------------------
    def flexibility(self, Bd: np.ndarray) -> np.ndarray:
        """``Bd (K^-1)[last, last] Bd^T`` for an (m, k) ``Bd`` (sparse or dense) acting on
        ``last`` (with a ``rotation``: ``K`` is ``Tᵀ K T`` here and ``Bd`` acts in its basis):
        ``S⁻¹`` from ``L_ΓΓ`` (LAPACK ``dpotri``), seen through the few entries per row of ``Bd``."""
        if self.k == 0:
            return np.zeros((Bd.shape[0], Bd.shape[0]))
        inverse, info = la.lapack.dpotri(self._Ltt, lower=1)  # S⁻¹ from its Cholesky factor
        if info != 0:
            raise FactorizationError(f"the interface Schur complement is singular (dpotri info {info})")
        inverse = np.tril(inverse) + np.tril(inverse, -1).T
        Bd = sp.csr_matrix(Bd)
        if np.all(np.diff(Bd.indptr) == 1):
            # one unknown per row (normal rows in the rotated basis): entries of S⁻¹, scaled
            at = self._pos[Bd.indices]
            return Bd.data[:, None] * inverse[np.ix_(at, at)] * Bd.data[None, :]
        Bp = Bd[:, np.argsort(self._pos)]  # columns in trailing-block order
        return np.asarray(Bp @ (Bp @ inverse).T)

    # -- solves, whole or in halves --------------------------------------------------------
    def _cholmod(self, v: np.ndarray, sys: int) -> np.ndarray:
        X = cvx_matrix(np.ascontiguousarray(v, dtype=float))
        cholmod.solve(self._F, X, sys=sys)
        return np.array(X).reshape(v.shape)

    def forward(self, b: np.ndarray) -> np.ndarray:
        """``y = L⁻¹ P Tᵀ b`` for a vector or an (n, j) block (factor order)."""
        b = np.asarray(b, dtype=float)
        if self.rotation is not None:
            b = self.rotation.T @ b
        return self._cholmod(b[self._perm], 4)

    def interface(self, y: np.ndarray) -> np.ndarray:
        """The ``last`` unknowns of ``K⁻¹ b`` (in the rotated basis) from ``y = forward(b)``:
        ``L_ΓΓ⁻ᵀ y_Γ``, dense and small."""
        x = la.solve_triangular(self._Ltt, y[self.n - self.k:], lower=True, trans="T", check_finite=False)
        return x[self._pos]

    def lift(self, g: np.ndarray) -> np.ndarray:
        """``forward`` of a load on the ``last`` unknowns alone, given as its (k,) or (k, j)
        values there (rotated basis): ``[0; L_ΓΓ⁻¹ g]``, dense and small."""
        g = np.asarray(g, dtype=float)
        gt = np.zeros_like(g)
        gt[self._pos] = g
        y = np.zeros((self.n,) + g.shape[1:])
        y[self.n - self.k:] = la.solve_triangular(self._Ltt, gt, lower=True, check_finite=False)
        return y

    def backward(self, y: np.ndarray) -> np.ndarray:
        """``x = T Pᵀ L⁻ᵀ y``: with ``y = forward(b)``, ``x = K⁻¹ b``."""
        z = self._cholmod(y, 5)
        x = np.empty_like(z)
        x[self._perm] = z
        return x if self.rotation is None else self.rotation @ x

    def solve(self, b: np.ndarray) -> np.ndarray:
        """``K^-1 b`` for a vector or an (n, j) block."""
        return self.backward(self.forward(b))
