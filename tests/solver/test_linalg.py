"""The interface-last factorization against dense linear algebra."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from solver.fe.linalg import InterfaceFactor


def laplacian_2d(n: int) -> sp.csr_matrix:
    T = sp.diags([-1, 2.1, -1], [-1, 0, 1], shape=(n, n))
    return (sp.kron(sp.eye(n), T) + sp.kron(T, sp.eye(n))).tocsr()


def test_flexibility_and_solve_match_dense_inverse():
    K = laplacian_2d(14)  # 196 unknowns, SPD
    rng = np.random.default_rng(0)
    last = np.sort(rng.choice(K.shape[0], 23, replace=False))
    f = InterfaceFactor(K, last, rng.permutation(K.shape[0]))  # any ordering of the rest
    Kinv = np.linalg.inv(K.toarray())
    Bd = rng.standard_normal((9, last.size))
    np.testing.assert_allclose(f.flexibility(Bd), Bd @ Kinv[np.ix_(last, last)] @ Bd.T, rtol=1e-10, atol=1e-12)
    b = rng.standard_normal(K.shape[0])
    np.testing.assert_allclose(f.solve(b), Kinv @ b, rtol=1e-10, atol=1e-12)


def test_split_solve_matches_dense_inverse():
    """forward / interface / lift / backward: ``K⁻¹b`` on ``last`` from the forward half
    alone, and ``K⁻¹(b - g)`` for a load g on ``last`` from one backward solve."""
    K = laplacian_2d(12)
    n = K.shape[0]
    rng = np.random.default_rng(4)
    last = np.sort(rng.choice(n, 17, replace=False))
    f = InterfaceFactor(K, last, rng.permutation(n))
    Kinv = np.linalg.inv(K.toarray())
    b, g = rng.standard_normal(n), rng.standard_normal(last.size)
    y = f.forward(b)
    np.testing.assert_allclose(f.interface(y), (Kinv @ b)[last], rtol=1e-10, atol=1e-12)
    G = np.zeros(n)
    G[last] = g
    np.testing.assert_allclose(f.backward(y - f.lift(g)), Kinv @ (b - G), rtol=1e-10, atol=1e-12)
    B = rng.standard_normal((n, 3))
    np.testing.assert_allclose(f.solve(B), Kinv @ B, rtol=1e-10, atol=1e-12)


def test_interface_split_over_several_supernodes():
    """Two unconnected bodies: the Schur complement is block diagonal and CHOLMOD stores its
    factor in separate supernodes, which the trailing block is read from."""
    K1, K2 = laplacian_2d(9), laplacian_2d(8)
    K = sp.block_diag([K1, K2], format="csr")
    n1 = K1.shape[0]
    last = np.r_[3, 40, 41, 70, n1 + 5, n1 + 30, n1 + 31]
    f = InterfaceFactor(K, last)
    Kinv = np.linalg.inv(K.toarray())
    Bd = np.random.default_rng(5).standard_normal((4, last.size))
    np.testing.assert_allclose(f.flexibility(Bd), Bd @ Kinv[np.ix_(last, last)] @ Bd.T, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(f.flexibility(np.eye(last.size)), Kinv[np.ix_(last, last)], rtol=1e-10, atol=1e-12)


def test_not_positive_definite_is_a_clear_error():
    from solver import SolverError
    from solver.fe.linalg import FactorizationError

    K = laplacian_2d(6) - 5.0 * sp.identity(36)
    with pytest.raises(FactorizationError, match="not positive definite") as caught:
        InterfaceFactor(K, np.array([0, 1]))
    assert isinstance(caught.value, SolverError)  # reported as a failed case, not a crash


def test_normal_and_full_factorizations_agree_on_a_model():
    """The two factorizations of a body (the interface nodes' normal unknowns last, or their
    normal and tangential ones) give the same normal flexibility and the same solves."""
    from solver import CaseSpec
    from solver.model import TunnelModel

    model = TunnelModel(CaseSpec(mesh=dict(interface_size=0.2, far_size=6.0)))
    m = model.m
    np.testing.assert_allclose(model.S_normal, model.S[:m, :m], rtol=1e-9, atol=1e-12 * np.abs(model.S).max())
    rng = np.random.default_rng(2)
    for body in (model.ground, model.lining):
        b = rng.standard_normal(body.body.n)
        x = body.backward(body.forward(b, "normal"), "normal")
        np.testing.assert_allclose(x, body.backward(body.forward(b, "all"), "all"), rtol=1e-9,
                                   atol=1e-12 * np.abs(x).max())
        normal, _ = body.factor("normal")
        full, _ = body.factor("all")
        assert normal.k == m and full.k > 1.9 * m  # one unknown per node, against two


def test_nested_dissection_of_a_p2_body():
    """The mesh ordering is a permutation of the body's unknowns; a node's unknowns stay
    together; the node of edge f is ``nv + f`` (on its edge, up to the curved interface's
    sagitta), ordered before both of its vertices."""
    from solver import CaseSpec
    from solver.fe.linalg import nested_dissection
    from solver.model import TunnelModel

    model = TunnelModel(CaseSpec(mesh=dict(interface_size=0.2, far_size=6.0)))
    for fb in (model.ground, model.lining):
        mesh, nodes = fb.body.basis.mesh, fb.body.node_of_dof()
        a, b = mesh.facets
        nv = int(mesh.t.max()) + 1
        assert mesh.doflocs.shape[1] == nv + a.size
        length = np.hypot(*(mesh.doflocs[:, a] - mesh.doflocs[:, b]))
        off = np.hypot(*(mesh.doflocs[:, nv:] - 0.5 * (mesh.doflocs[:, a] + mesh.doflocs[:, b])))
        assert np.all(off < 0.05 * length)
        order = nested_dissection(mesh, nodes)
        assert np.array_equal(np.sort(order), np.arange(nodes.size))
        node_order = nodes[order]
        changes = np.flatnonzero(np.diff(node_order)) + 1
        assert np.unique(node_order).size == changes.size + 1  # each node's unknowns contiguous
        first = np.full(mesh.doflocs.shape[1], np.inf)
        np.minimum.at(first, node_order, np.arange(order.size))
        edge = first[nv:]
        ok = np.isfinite(edge) & np.isfinite(first[a]) & np.isfinite(first[b])
        assert np.all(edge[ok] < np.minimum(first[a], first[b])[ok])
        # what it is for: a factor a small fraction of what an arbitrary order gives
        # (measured 0.02 and 0.08 of a random order's at this mesh)
        K, _ = fb.matrix()
        keep = slice(None) if fb._keep is None else fb._keep
        order = nested_dissection(mesh, nodes[keep])
        entries = {name: _factor_entries(K, p) for name, p in
                   (("nd", order), ("random", np.random.default_rng(0).permutation(K.shape[0])))}
        assert entries["nd"] < 0.2 * entries["random"], entries


def _factor_entries(K: sp.spmatrix, order: np.ndarray) -> int:
    """Entries of CHOLMOD's factor of K in ``order``."""
    from solver.fe.linalg import Cholesky

    return Cholesky(K, order).entries


def test_factorization_releases_the_gil():
    """CHOLMOD runs without the GIL (ctypes releases it): a Python thread keeps running while
    another thread factorizes, so a worker's event loop is not blocked by a long
    factorization. The longest pause of the counting thread is compared with the numeric
    factorization's own length, not with a clock limit."""
    import threading
    import time

    from solver.fe.linalg import Cholesky

    K = laplacian_2d(320)  # 102 400 unknowns
    perm = _grid_dissection(320)
    done, stamps, seconds = threading.Event(), [], {}

    def factorize():
        seconds.update(Cholesky(K, perm).seconds)
        done.set()

    worker = threading.Thread(target=factorize)
    worker.start()
    while not done.is_set():
        stamps.append(time.perf_counter())
    worker.join()
    longest_pause = float(np.max(np.diff(stamps)))
    assert seconds["numeric"] > 0.02, seconds  # long enough for the comparison to mean something
    assert longest_pause < 0.5 * seconds["numeric"], (longest_pause, seconds)


def _grid_dissection(n: int) -> np.ndarray:
    """A nested-dissection order of an n x n grid (recursive halving, separators last)."""
    def order(rows: range, cols: range) -> list[int]:
        if len(rows) * len(cols) <= 64:
            return [r * n + c for r in rows for c in cols]
        if len(rows) >= len(cols):
            mid = rows.start + len(rows) // 2
            return order(range(rows.start, mid), cols) + order(range(mid + 1, rows.stop), cols) \
                + [mid * n + c for c in cols]
        mid = cols.start + len(cols) // 2
        return order(rows, range(cols.start, mid)) + order(rows, range(mid + 1, cols.stop)) \
            + [r * n + mid for r in rows]
    return np.array(order(range(n), range(n)), dtype=np.int64)


def test_an_invalid_permutation_is_an_error_not_a_crash():
    """CHOLMOD checks the permutation it is given; its refusal surfaces as an error."""
    from solver.fe.linalg import Cholesky

    K = laplacian_2d(5)
    perm = np.arange(K.shape[0])
    perm[3] = perm[4]  # not a permutation
    with pytest.raises(RuntimeError, match="CHOLMOD analysis failed"):
        Cholesky(K, perm)
    assert Cholesky(K, np.arange(K.shape[0])).entries > 0  # the library still works after it
