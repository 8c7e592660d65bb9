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
ACM TOMS 35(3), 2008), the CHOLMOD 3 library that cvxopt's wheels bundle, called
through its C interface (:class:`Cholesky`): on scipy's arrays as they are (no copy into
another sparse format), with the GIL released while it runs, several right-hand sides
in one sweep over the factor, and the trailing block read in place from the factor.
The structs are those of ``cholmod_core.h`` (CHOLMOD 3); the library's version and the
defaults it writes into ``cholmod_common`` are checked before first use, so a different
layout stops with an error instead of reading the wrong fields.
"""
from __future__ import annotations

import ctypes
import os
import threading
import time
import weakref

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp
from cvxopt import cholmod as _cvxopt_cholmod
from threadpoolctl import ThreadpoolController

from ..errors import SolverError


def blas_thread_count() -> int:
    """BLAS threads the solver allows itself: ``TUNNEL_CONTACT_BLAS_THREADS`` (1 unset), read at
    each call (a forked worker's own). Its dense work is small (condensed interface blocks of a
    few hundred rows); OpenBLAS's threads spinning against the supernodal factorization and each
    other made a plain process's case take 2.6-6.2 s instead of 0.45 s now and then (issue 24)."""
    return max(1, int(os.environ.get("TUNNEL_CONTACT_BLAS_THREADS", "1") or 1))


_CONTROLLER: ThreadpoolController | None = None


def blas_threads():
    """Context limiting every loaded BLAS (numpy's, scipy's, CHOLMOD's OpenBLAS) to
    ``blas_thread_count()`` threads, whatever process the solver runs in (CLI, notebook,
    worker); about 40 µs to enter (the libraries are looked up once, on first use)."""
    global _CONTROLLER
    if _CONTROLLER is None:
        _CONTROLLER = ThreadpoolController()
    return _CONTROLLER.limit(limits=blas_thread_count(), user_api="blas")


class FactorizationError(SolverError):
    """A stiffness matrix that is not positive definite (a body not held): a solver failure
    like any other, recorded with the case and reported by the CLI and the service."""


# -- CHOLMOD's C interface (cholmod_core.h, CHOLMOD 3) ---------------------------------------
# cvxopt's extension module links libcholmod; looking symbols up through its handle finds
# them in its dependencies, whatever the wheel names the library file. A CDLL's calls run
# without the GIL (tests/solver/test_linalg.py::test_factorization_releases_the_gil).
_lib = ctypes.CDLL(_cvxopt_cholmod.__file__)
_size, _double, _int, _ptr = ctypes.c_size_t, ctypes.c_double, ctypes.c_int, ctypes.c_void_p
_LONG, _REAL, _DOUBLE = 2, 1, 0  # itype, xtype, dtype
_GIVEN, _AMD, _METIS, _NESDIS, _SUPERNODAL = 1, 2, 3, 4, 2
_SYS_L, _SYS_LT = 4, 5  # solve L x = b, Lᵀ x = b
_NOT_POSDEF, _OUT_OF_MEMORY = 1, -2


class _Method(ctypes.Structure):
    _fields_ = [(name, _double) for name in ("lnz", "fl", "prune_dense", "prune_dense2", "nd_oksep")] \
        + [("other_1", _double * 4), ("nd_small", _size), ("other_2", _size * 4)] \
        + [(name, _int) for name in ("aggressive", "order_for_lu", "nd_compress", "nd_camd", "nd_components",
                                     "ordering")] \
        + [("other_3", _size * 4)]


class _Common(ctypes.Structure):
    """``cholmod_common`` up to the statistics this module reads, then room for the rest."""

    _fields_ = [("dbound", _double), ("grow0", _double), ("grow1", _double), ("grow2", _size),
                ("maxrank", _size), ("supernodal_switch", _double)] \
        + [(name, _int) for name in ("supernodal", "final_asis", "final_super", "final_ll", "final_pack",
                                     "final_monotonic", "final_resymbol")] \
        + [("zrelax", _double * 3), ("nrelax", _size * 3)] \
        + [(name, _int) for name in ("prefer_zomplex", "prefer_upper", "quick_return_if_not_posdef",
                                     "prefer_binary", "print", "precise", "try_catch")] \
        + [("error_handler", _ptr)] + [(name, _int) for name in ("nmethods", "current", "selected")] \
        + [("method", _Method * 10), ("postorder", _int), ("default_nesdis", _int), ("metis_memory", _double),
           ("metis_dswitch", _double), ("metis_nswitch", _size), ("nrow", _size), ("mark", ctypes.c_int64),
           ("iworksize", _size), ("xworksize", _size)] \
        + [(name, _ptr) for name in ("Flag", "Head", "Xwork", "Iwork")] \
        + [(name, _int) for name in ("itype", "dtype", "no_workspace_reallocate", "status")] \
        + [("rest", ctypes.c_char * 8192)]  # statistics and GPU fields: 1.2 kB in CHOLMOD 3.0


class _Sparse(ctypes.Structure):
    _fields_ = [(name, _size) for name in ("nrow", "ncol", "nzmax")] \
        + [(name, _ptr) for name in ("p", "i", "nz", "x", "z")] \
        + [(name, _int) for name in ("stype", "itype", "xtype", "dtype", "sorted", "packed")]


class _Dense(ctypes.Structure):
    _fields_ = [(name, _size) for name in ("nrow", "ncol", "nzmax", "d")] \
        + [("x", _ptr), ("z", _ptr), ("xtype", _int), ("dtype", _int)]


class _Factor(ctypes.Structure):
    _fields_ = [(name, _size) for name in ("n", "minor")] \
        + [(name, _ptr) for name in ("Perm", "ColCount", "IPerm")] \
        + [("nzmax", _size)] \
        + [(name, _ptr) for name in ("p", "i", "x", "z", "nz", "next", "prev")] \
        + [(name, _size) for name in ("nsuper", "ssize", "xsize", "maxcsize", "maxesize")] \
        + [(name, _ptr) for name in ("super", "pi", "px", "s")] \
        + [(name, _int) for name in ("ordering", "is_ll", "is_super", "is_monotonic", "itype", "xtype", "dtype",
                                     "useGPU")]


_common_p, _factor_p, _dense_p = ctypes.POINTER(_Common), ctypes.POINTER(_Factor), ctypes.POINTER(_Dense)
for _name, _res, _args in (
        ("cholmod_l_version", _int, [ctypes.POINTER(_int * 3)]),
        ("cholmod_l_start", _int, [_common_p]),
        ("cholmod_l_analyze_p", _factor_p, [ctypes.POINTER(_Sparse), _ptr, _ptr, _size, _common_p]),
        ("cholmod_l_factorize", _int, [ctypes.POINTER(_Sparse), _factor_p, _common_p]),
        ("cholmod_l_free_factor", _int, [ctypes.POINTER(_factor_p), _common_p]),
        ("cholmod_l_solve", _dense_p, [_int, _factor_p, _dense_p, _common_p]),
        ("cholmod_l_free_dense", _int, [ctypes.POINTER(_dense_p), _common_p])):
    getattr(_lib, _name).restype, getattr(_lib, _name).argtypes = _res, _args

_version = (_int * 3)()
_lib.cholmod_l_version(ctypes.byref(_version))
if _version[0] != 3:
    raise ImportError(f"tunnel-contact reads CHOLMOD 3's structs; cvxopt bundles CHOLMOD {tuple(_version)}")

_thread = threading.local()


def _common() -> _Common:
    """This thread's ``cholmod_common`` (CHOLMOD's workspace is not shared between threads),
    set for a supernodal LLᵀ in the permutation given, with CHOLMOD's postordering."""
    c = getattr(_thread, "common", None)
    if c is None:
        c = _Common()
        _lib.cholmod_l_start(ctypes.byref(c))
        defaults = (c.grow0, c.grow2, c.maxrank, c.supernodal_switch, tuple(c.zrelax), tuple(c.nrelax),
                    tuple(m.ordering for m in c.method[:4]), c.method[0].nd_small, c.postorder,
                    c.metis_nswitch, c.itype, c.status)
        if defaults != (1.2, 5, 8, 40.0, (0.8, 0.1, 0.05), (4, 16, 48), (_GIVEN, _AMD, _METIS, _NESDIS), 200, 1,
                        3000, _LONG, 0):
            raise RuntimeError("unexpected cholmod_common layout (cvxopt's CHOLMOD changed)")
        c.print, c.supernodal, c.nmethods = 0, _SUPERNODAL, 1  # method[0]: the permutation given
        _thread.common = c
    return c


def _failure(c: _Common, what: str) -> Exception:
    """The error for a CHOLMOD call that failed, from the status it left in ``c``."""
    return (MemoryError if c.status == _OUT_OF_MEMORY else RuntimeError)(f"CHOLMOD {what} failed (status {c.status})")


def _free_factor(address: int) -> None:
    _lib.cholmod_l_free_factor(ctypes.byref(ctypes.cast(address, _factor_p)), _common())


def _csr(K: sp.spmatrix) -> sp.csr_matrix:
    """``K`` in CSR, the same object when it is (its canonical-format flag is kept: scipy
    checks it again, a pass over the matrix, for every new wrapper)."""
    return K if sp.isspmatrix_csr(K) else sp.csr_matrix(K)


def _sparse(K: sp.csr_matrix):
    """CHOLMOD's view of a canonical CSR ``K`` (its CSC transpose, the lower triangle used) and the
    arrays it points to (keep them alive while CHOLMOD reads)."""
    n = K.shape[0]
    indptr, indices = K.indptr.astype(np.int64), K.indices.astype(np.int64)
    data = np.ascontiguousarray(K.data, dtype=float)
    A = _Sparse(n, n, K.nnz, indptr.ctypes.data, indices.ctypes.data, None, data.ctypes.data, None,
                -1, _LONG, _REAL, _DOUBLE, 1, 1)
    return A, (indptr, indices, data)


def _view(address: int, size: int, ctype) -> np.ndarray:
    return np.ctypeslib.as_array(ctypes.cast(address, ctypes.POINTER(ctype)), (size,))


class Cholesky:
    """CHOLMOD's supernodal ``P K Pᵀ = L Lᵀ`` of a sparse SPD ``K`` with ``P`` from ``perm``
    (position j of the factor holds unknown ``perm[j]``; CHOLMOD may postorder it, see
    :attr:`perm`). ``K`` is read in place: its CSR arrays are the CSC arrays of ``Kᵀ = K``,
    of which CHOLMOD uses the lower triangle.

    Attributes: ``perm`` the final permutation, ``entries`` the entries of ``L``,
    ``seconds`` of the symbolic and numeric phases.
    Raises :class:`FactorizationError` if ``K`` is not positive definite.
    """

    def __init__(self, K: sp.spmatrix, perm: np.ndarray, postorder: bool = True):
        K = _csr(K)
        K.sum_duplicates()  # canonical: sorted, no duplicates (a no-op when already so)
        n = K.shape[0]
        A, keep = _sparse(K)
        P = np.ascontiguousarray(perm, dtype=np.int64)
        c = _common()
        c.postorder = int(postorder)
        t0 = time.perf_counter()
        L = _lib.cholmod_l_analyze_p(ctypes.byref(A), P.ctypes.data, None, 0, ctypes.byref(c))
        t1 = time.perf_counter()
        if not L:
            raise _failure(c, "analysis")
        self._L, self.n = L, n
        weakref.finalize(self, _free_factor, ctypes.addressof(L.contents))
        self._numeric(A, c)
        self.seconds = {"symbolic": t1 - t0, "numeric": time.perf_counter() - t1}
        #: the unknown at each factor position
        self.perm = _view(self._struct.Perm, n, ctypes.c_int64).copy()
        del keep

    def refactor(self, K: sp.spmatrix) -> None:
        """Factorize ``K``, whose pattern is the one analysed at construction (other values), into
        this factor: the ordering and symbolic analysis are reused, :attr:`perm` stays."""
        K = _csr(K)
        K.sum_duplicates()
        A, keep = _sparse(K)
        self._numeric(A, _common())
        del keep

    def _numeric(self, A, c) -> None:
        ok = _lib.cholmod_l_factorize(ctypes.byref(A), self._L, ctypes.byref(c))
        f = self._struct
        if c.status == _NOT_POSDEF or f.minor < self.n:
            raise FactorizationError(f"the stiffness matrix is not positive definite (pivot {f.minor} of {self.n})")
        if not ok or c.status < 0:
            raise _failure(c, "factorization")

    @property
    def _struct(self) -> _Factor:
        f = self._L.contents
        if not (f.n == self.n and f.is_super and f.is_ll and f.itype == _LONG and f.xtype == _REAL
                and f.dtype == _DOUBLE):
            raise RuntimeError("unexpected CHOLMOD factor layout (cvxopt's CHOLMOD changed)")
        return f

    def _supernodes(self):
        f = self._struct
        ns, it = f.nsuper, ctypes.c_int64
        return (ns, *(_view(a, ns + 1, it) for a in (f.super, f.pi, f.px)),
                _view(f.s, f.ssize, it), _view(f.x, f.xsize, ctypes.c_double))

    @property
    def entries(self) -> int:
        """Entries of ``L`` (the lower triangle of each supernode's dense block)."""
        _, sup, pi, _, _, _ = self._supernodes()
        cols, rows = np.diff(sup), np.diff(pi)
        return int(np.sum(rows * cols - cols * (cols - 1) // 2))

    def solve(self, system: int, b: np.ndarray) -> np.ndarray:
        """``L⁻¹ b`` (``system = _SYS_L``) or ``L⁻ᵀ b`` (``_SYS_LT``) in factor order, for a
        vector or an (n, j) block: the j columns in one sweep over the factor."""
        B = np.asfortranarray(b, dtype=float)
        j = 1 if B.ndim == 1 else B.shape[1]
        rhs = _Dense(self.n, j, self.n * j, self.n, B.ctypes.data, None, _REAL, _DOUBLE)
        c = _common()
        X = _lib.cholmod_l_solve(system, self._L, ctypes.byref(rhs), ctypes.byref(c))
        if not X:
            raise _failure(c, "solve")
        try:
            x = np.array(_view(X.contents.x, self.n * j, ctypes.c_double).reshape(j, self.n).T, order="F")
        finally:
            _lib.cholmod_l_free_dense(ctypes.byref(X), ctypes.byref(c))
        return x.reshape(b.shape)

    def trailing_block(self, k: int) -> np.ndarray:
        """The dense lower trailing ``k x k`` block of ``L``, copied out of the factor.

        Each supernode stores its columns ``super[s]:super[s+1]`` as a dense column-major
        block of the rows ``s[pi[s]:pi[s+1]]`` at ``x[px[s]:]``; the supernodes covering the
        last k columns hold ``L_ΓΓ``.
        """
        n = self.n
        ns, sup, pi, px, rows_of, x = self._supernodes()
        if sup[ns] != n or pi[ns] > rows_of.size or px[ns] > x.size:
            raise RuntimeError("inconsistent CHOLMOD supernodes")
        start = n - k
        s = ns - 1
        c0, nr = int(sup[s]), int(pi[s + 1] - pi[s])
        if c0 <= start and nr == n - c0 and np.array_equal(rows_of[pi[s]: pi[s + 1]], np.arange(c0, n)):
            # one dense supernode holds the trailing columns (as for any connected interface)
            Ltt = x[px[s]: px[s] + nr * nr].reshape(nr, nr).T[start - c0:, start - c0:].copy()
        else:
            Ltt = np.zeros((k, k))
            while s >= 0 and sup[s + 1] > start:
                c0, c1 = int(sup[s]), int(sup[s + 1])
                nr = int(pi[s + 1] - pi[s])
                block = x[px[s]: px[s] + nr * (c1 - c0)].reshape(c1 - c0, nr).T
                rows = rows_of[pi[s]: pi[s + 1]]
                if not np.array_equal(rows[: c1 - c0], np.arange(c0, c1)):
                    raise RuntimeError("inconsistent CHOLMOD supernode rows")
                r, c = rows >= start, np.arange(c0, c1) >= start
                Ltt[np.ix_(rows[r] - start, np.arange(c0, c1)[c] - start)] = block[np.ix_(r, c)]
                s -= 1
        Ltt = np.tril(Ltt)
        if not np.all(np.diag(Ltt) > 0.0):
            raise RuntimeError("the CHOLMOD factor read in place has a non-positive pivot")
        return Ltt


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


def interface_last(order: np.ndarray, last: np.ndarray) -> np.ndarray:
    """``order`` with the unknowns ``last`` taken out and put at the end, in their own order."""
    at_end = np.zeros(order.size, dtype=bool)
    at_end[last] = True
    return np.concatenate([order[~at_end[order]], last])


class InterfaceFactor:
    """Cholesky factorization of an SPD matrix with the ``last`` unknowns ordered last.

    Parameters
    ----------
    K : (n, n) sparse SPD matrix.
    last : (k,) indices of the interface unknowns.
    order : (n,) optional fill-reducing ordering of the unknowns (:func:`nested_dissection`);
        the factor uses it with ``last`` moved to the end. Default: as numbered.

    Raises :class:`FactorizationError` if the matrix is not positive definite.
    """

    def __init__(self, K: sp.spmatrix, last: np.ndarray, order: np.ndarray | None = None):
        K = _csr(K)
        n = K.shape[0]
        self.last = np.asarray(last, dtype=np.int64)
        perm = interface_last(np.arange(n) if order is None else np.asarray(order), self.last)
        self.n, self.k = n, self.last.size
        # CHOLMOD postorders the elimination tree (4 % less factorization time at 128k
        # unknowns): a permutation of ours that keeps a connected interface block trailing.
        # An interface in several unconnected parts could be moved apart: then ours as given.
        for postorder in (True, False):
            self._chol = Cholesky(K, perm, postorder)
            self._perm = self._chol.perm
            if np.array_equal(np.sort(self._perm[n - self.k:]), np.sort(self.last)):
                break
        else:
            raise RuntimeError("CHOLMOD did not keep the interface unknowns last")
        self._Ltt = self._chol.trailing_block(self.k)
        where = np.empty(n, np.int64)
        where[self._perm] = np.arange(n)
        #: factor position of each unknown, and the trailing-block position of each of ``last``
        self._where, self._pos = where, where[self.last] - (n - self.k)

    # -- the interface -----------------------------------------------------------------
    def flexibility(self, Bd: np.ndarray) -> np.ndarray:
        """``Bd (K^-1)[last, last] Bd^T`` for an (m, k) ``Bd`` (sparse or dense) acting on
        ``last``:
        ``S⁻¹`` from ``L_ΓΓ`` (LAPACK ``dpotri``), seen through the few entries per row of
        ``Bd``; exactly symmetric."""
        if self.k == 0:
            return np.zeros((Bd.shape[0], Bd.shape[0]))
        inverse, info = la.lapack.dpotri(self._Ltt, lower=1)  # S⁻¹'s lower triangle; L_ΓΓ's zeros above
        if info != 0:
            raise FactorizationError(f"the interface Schur complement is singular (dpotri info {info})")
        diagonal = inverse.diagonal().copy()
        inverse += inverse.T
        np.fill_diagonal(inverse, diagonal)
        Bd = sp.csr_matrix(Bd)
        if np.all(np.diff(Bd.indptr) == 1):
            # one unknown per row (interface rows in a body's skew basis): entries of S⁻¹, scaled;
            # no gather when the rows are the trailing block's order (``last`` in row order)
            at = self._pos[Bd.indices]
            if not np.array_equal(at, np.arange(self.k)):
                inverse = inverse[np.ix_(at, at)]
            inverse *= Bd.data[:, None]
            inverse *= Bd.data[None, :]
            return inverse
        Bp = Bd[:, np.argsort(self._pos)]  # columns in trailing-block order
        F = np.asarray(Bp @ (Bp @ inverse).T)
        return 0.5 * (F + F.T)

    # -- solves, whole or in halves --------------------------------------------------------
    def forward(self, b: np.ndarray) -> np.ndarray:
        """``y = L⁻¹ P b`` for a vector or an (n, j) block (factor order)."""
        b = np.asarray(b, dtype=float)
        return self._chol.solve(_SYS_L, b[self._perm])

    def interface(self, y: np.ndarray) -> np.ndarray:
        """The ``last`` unknowns of ``K⁻¹ b`` from ``y = forward(b)``:
        ``L_ΓΓ⁻ᵀ y_Γ``, dense and small."""
        return self.interface_of(y[self.n - self.k:])

    def interface_of(self, tail: np.ndarray) -> np.ndarray:
        """:meth:`interface` from ``y``'s trailing ``k`` entries ``tail`` alone."""
        return la.solve_triangular(self._Ltt, tail, lower=True, trans="T", check_finite=False)[self._pos]

    def lift(self, g: np.ndarray) -> np.ndarray:
        """``forward`` of a load on the ``last`` unknowns alone, given as its (k,) or (k, j)
        values there: ``[0; L_ΓΓ⁻¹ g]``, dense and small."""
        g = np.asarray(g, dtype=float)
        y = np.zeros((self.n,) + g.shape[1:])
        y[self.n - self.k:] = self.lift_of(g)
        return y

    def lift_of(self, g: np.ndarray) -> np.ndarray:
        """:meth:`lift`'s trailing ``k`` entries (the others are zero)."""
        g = np.asarray(g, dtype=float)
        gt = np.zeros_like(g)
        gt[self._pos] = g
        return la.solve_triangular(self._Ltt, gt, lower=True, check_finite=False)

    @property
    def cholesky(self) -> Cholesky:
        return self._chol

    def positions(self, unknowns: np.ndarray) -> np.ndarray:
        """The factor position of each of ``unknowns``."""
        return self._where[unknowns]

    def backward(self, y: np.ndarray) -> np.ndarray:
        """``x = Pᵀ L⁻ᵀ y``: with ``y = forward(b)``, ``x = K⁻¹ b``."""
        return self._chol.solve(_SYS_LT, y)[self._where]

    def solve(self, b: np.ndarray) -> np.ndarray:
        """``K^-1 b`` for a vector or an (n, j) block."""
        return self.backward(self.forward(b))
