"""Solver benchmark: the default case at three mesh sizes.

Per size: DOF, interface nodes, seconds for meshing, assembly, the *floor*
(one factorization plus one solve of the bolted system, i.e. the linear
elastic problem with the lining held at the invert: no contact solver can be
cheaper), the full contact solve with each inner solver (interface
condensation + bolt search + displacement recovery), iterations, and the ratio
contact / floor. All timings of one size come from the same run.

    python -m bench.solver [--json] [--sizes h:far,h:far,...]
"""
from __future__ import annotations

import argparse
import json
import time

import numpy as np
import scipy.sparse as sp

from solver import CaseSpec
from solver.assembly import assemble_system
from solver.contact import solve_contact
from solver.flexibility import condense_interface, interface_operator, recover_displacements
from solver.linalg import InterfaceFactor
from solver.mesh import build_mesh

SIZES = [(0.1, 4.0), (0.04, 1.6), (0.02, 0.5)]


def _floor(system, iface) -> float:
    """Factor and solve the bolted two-body system (bolt at the invert, by augmentation)."""
    g, l = system.ground, system.lining
    K = sp.block_diag([g.K, l.K], format="csr")
    b = sp.hstack([interface_operator(g, iface.ground_node[-1:], iface.normal[:, -1:], 1.0),
                   interface_operator(l, iface.lining_node[-1:], iface.normal[:, -1:], -1.0)]).tocsr()
    k = float(K.diagonal().max())
    KA = (K + k * (b.T @ b)).tocsr()
    f = np.concatenate([g.f, l.f])
    groups = np.concatenate([g.node_of_dof(), l.node_of_dof() + g.free_of.shape[1]])
    t0 = time.perf_counter()
    factor = InterfaceFactor(KA, np.array([], dtype=np.int64), groups)
    factor.solve(f)
    return time.perf_counter() - t0


def bench_size(h: float, far: float) -> dict:
    spec = CaseSpec(mesh=dict(interface_size=h, far_size=far))
    t0 = time.perf_counter()
    mesh = build_mesh(spec)
    t_mesh = time.perf_counter() - t0
    t0 = time.perf_counter()
    system = assemble_system(spec, mesh)
    t_asm = time.perf_counter() - t0
    iface = mesh.interface
    row = {"interface_size": h, "far_size": far, "dof": system.ground.n + system.lining.n,
           "interface_nodes": iface.size, "mesh_s": t_mesh, "assembly_s": t_asm,
           "floor_s": _floor(system, iface)}
    for inner in ("active-set", "uzawa"):
        t0 = time.perf_counter()
        dual, g, l = condense_interface(system, iface, spec.geometry.gap)
        sol = solve_contact(dual, iface.theta, inner=inner, tol=spec.solver.tolerance,
                            max_iterations=spec.solver.max_iterations)
        recover_displacements(g, l, sol.lam, sol.a, iface.weight)
        t = time.perf_counter() - t0
        row[f"{inner}_s"] = t
        row[f"{inner}_iterations"] = sol.iterations
        row[f"{inner}_ratio"] = t / row["floor_s"]
    return row


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print machine-readable JSON")
    ap.add_argument("--sizes", help="comma-separated interface_size:far_size pairs")
    args = ap.parse_args(argv)
    sizes = SIZES if not args.sizes else [tuple(map(float, s.split(":"))) for s in args.sizes.split(",")]
    rows = [bench_size(h, f) for h, f in sizes]
    if args.json:
        print(json.dumps(rows, indent=2))
        return
    head = ("DOF", "iface", "mesh s", "asm s", "floor s", "act-set s", "iters", "ratio", "uzawa s", "iters", "ratio")
    print(" | ".join(f"{x:>9}" for x in head))
    for r in rows:
        vals = (r["dof"], r["interface_nodes"], f"{r['mesh_s']:.2f}", f"{r['assembly_s']:.2f}",
                f"{r['floor_s']:.2f}", f"{r['active-set_s']:.2f}", r["active-set_iterations"],
                f"{r['active-set_ratio']:.2f}", f"{r['uzawa_s']:.2f}", r["uzawa_iterations"],
                f"{r['uzawa_ratio']:.2f}")
        print(" | ".join(f"{x:>9}" for x in vals))


if __name__ == "__main__":
    main()
