"""Fill-reducing orderings of the ground at one mesh size, for CHOLMOD's Cholesky.

For each ordering: seconds to find it, then CHOLMOD's symbolic and numeric factorization
of the ground with nothing ordered last (the floor's) and with the interface normals last
(the contact solve's), and the entries of each factor. Orderings:

- ``vertex-nd``: METIS nested dissection of the P2 mesh's vertex graph, edge nodes placed
  with their earlier vertex (:func:`solver.fe.linalg.nested_dissection`, what the solver uses);
- ``node-nd``: METIS nested dissection of the whole node graph (what the solver used with
  SuperLU);
- ``amd``: approximate minimum degree of the node graph (cvxopt's AMD).

Each figure is the least of ``--repeat`` timings, the orderings alternating.

    python -m bench.ordering [--json] [--size h:far] [--repeat N]
"""
from __future__ import annotations

if __name__ == "__main__":
    from bench import one_blas_thread

    one_blas_thread()

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
import scipy.sparse as sp  # noqa: E402

from bench import print_rows  # noqa: E402


def _node_graph(K: sp.spmatrix, nodes: np.ndarray) -> tuple[sp.csr_matrix, np.ndarray]:
    _, g = np.unique(nodes, return_inverse=True)
    n = K.shape[0]
    P = sp.csr_matrix((np.ones(n), (g, np.arange(n))), shape=(g.max() + 1, n))
    G = (P @ abs(K) @ P.T).tocsr()
    G.setdiag(0)
    G.eliminate_zeros()
    G.sort_indices()
    return G, g


def _expand(node_order: np.ndarray, g: np.ndarray) -> np.ndarray:
    rank = np.empty(node_order.size, np.int64)
    rank[node_order] = np.arange(node_order.size)
    return np.argsort(rank[g], kind="stable")


def node_nd(K, nodes):
    import pymetis

    G, g = _node_graph(K, nodes)
    order, _ = pymetis.nested_dissection(adjacency=pymetis.CSRAdjacency(G.indptr, G.indices))
    return _expand(np.asarray(order), g)


def node_amd(K, nodes):
    from cvxopt import amd
    from cvxopt import matrix as cvx_matrix
    from cvxopt import spmatrix as cvx_spmatrix

    G, g = _node_graph(K, nodes)
    L = sp.tril(G + sp.identity(G.shape[0]), format="coo")
    pattern = cvx_spmatrix(cvx_matrix(L.data), cvx_matrix(L.row.astype(np.int64)), cvx_matrix(L.col.astype(np.int64)),
                           L.shape)
    return _expand(np.asarray(amd.order(pattern, "L")).ravel(), g)


def main(argv=None) -> None:
    from solver import CaseSpec
    from solver.fe.flexibility import in_row_order
    from solver.fe.linalg import Cholesky, interface_last, nested_dissection
    from solver.model import TunnelModel

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--size", default="0.03:1", help="interface_size:far_size")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    h, far = map(float, args.size.split(":"))
    model = TunnelModel(CaseSpec(mesh=dict(interface_size=h, far_size=far)))
    fb = model.ground
    K = fb.body.K
    nodes = fb.body.node_of_dof()
    last = in_row_order(fb.B[: fb.m])  # the normal unknowns (skew basis), as the solver orders them
    orderings = {"vertex-nd": lambda: nested_dissection(fb.body.basis.mesh, nodes),
                 "node-nd": lambda: node_nd(K, nodes), "amd": lambda: node_amd(K, nodes)}
    best: dict[tuple[str, str], float] = {}
    size: dict[tuple[str, str], int] = {}
    for _ in range(args.repeat):
        for name, find in orderings.items():
            t0 = time.perf_counter()
            order = find()
            times = {"order": time.perf_counter() - t0}
            for kind, p in (("free", order), ("last", interface_last(order, last))):
                factor = Cholesky(K, p)
                times[f"{kind}_symbolic"], times[f"{kind}_numeric"] = (factor.seconds["symbolic"],
                                                                       factor.seconds["numeric"])
                size[(name, kind)] = factor.entries
            for key, value in times.items():
                best[(name, key)] = min(value, best.get((name, key), np.inf))
    rows = []
    for name in orderings:
        row = {"ordering": name, "dof": K.shape[0], "interface_unknowns": last.size}
        row.update({f"{key}_s": best[(name, key)] for key in
                    ("order", "free_symbolic", "free_numeric", "last_symbolic", "last_numeric")})
        row["free_nnz_L"], row["last_nnz_L"] = size[(name, "free")], size[(name, "last")]
        row["free_total_s"] = row["order_s"] + row["free_symbolic_s"] + row["free_numeric_s"]
        row["last_total_s"] = row["order_s"] + row["last_symbolic_s"] + row["last_numeric_s"]
        rows.append(row)
    print_rows(rows, as_json=args.json)


if __name__ == "__main__":
    main()
