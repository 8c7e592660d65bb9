"""Solver benchmark: the default case at three mesh sizes, per stage, through the one
solver path (:class:`solver.model.TunnelModel`).

Per size: DOF, interface nodes, seconds for meshing, assembly, factorization with the
interface flexibility, the *floor* (factorizing both bodies plus one solve each: the
linear elastic problem, which no contact solve can beat), then per inner solver the
contact stage (stage loads, stage-1 solve, bolt search, recovery) and the whole
``run_case``; the ratio (factorization + contact) / floor. All timings of one size
come from the same run.

    python -m bench.solver [--json] [--sizes h:far,h:far,...]
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from bench import print_rows
from solver import CaseSpec, run_case
from solver.linalg import InterfaceFactor
from solver.model import TunnelModel

SIZES = [(0.1, 4.0), (0.05, 2.0), (0.025, 1.0)]


def _floor(model: TunnelModel) -> float:
    t0 = time.perf_counter()
    for fb in (model.ground, model.lining):
        K, groups = fb.matrix()  # what the model factorizes, with nothing ordered last
        InterfaceFactor(K, np.array([], dtype=np.int64), groups).solve(np.ones(K.shape[0]))
    return time.perf_counter() - t0


def bench_size(h: float, far: float) -> dict:
    spec = CaseSpec(mesh=dict(interface_size=h, far_size=far))
    model = TunnelModel(spec)
    row = {"interface_size": h, "far_size": far, "dof": model.ground.body.n + model.lining.body.n,
           "interface_nodes": model.m, **{f"{k}_s": v for k, v in model.timings.items()},
           "floor_s": _floor(model)}
    t0 = time.perf_counter()
    model.stage_loads(spec)  # unit load vectors: assembled once per model, as in a sweep
    row["stage_loads_s"] = time.perf_counter() - t0
    for inner in ("active-set", "uzawa"):
        case = spec.model_copy(update={"solver": spec.solver.model_copy(update={"inner": inner})})
        t0 = time.perf_counter()
        sol = model.solve(case)
        row[f"{inner}_contact_s"] = time.perf_counter() - t0
        row[f"{inner}_iterations"] = sol.iterations
        row[f"{inner}_ratio"] = (model.timings["factorization"] + row[f"{inner}_contact_s"]) / row["floor_s"]
    t0 = time.perf_counter()
    ds = run_case(spec)
    row["run_case_s"] = time.perf_counter() - t0
    row["max_abs_moment_kNm"] = float(ds.max_abs_moment) / 1e3
    return row


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--sizes", default=",".join(f"{h}:{f}" for h, f in SIZES))
    args = ap.parse_args(argv)
    rows = [bench_size(*map(float, s.split(":"))) for s in args.sizes.split(",")]
    print_rows(rows, as_json=args.json)


if __name__ == "__main__":
    main()
