"""Solver benchmark: the default case at three mesh sizes, per stage, through the one
solver path (:class:`solver.model.TunnelModel`).

Per size: DOF, interface nodes, seconds for meshing, assembly, factorization, the
*floor* (factorizing both bodies plus one solve each: the linear elastic problem, which
no contact solve can beat), the interface flexibility, then the contact stage (stage
loads, forward solves, bolt search, backward solves) three times on the one model: the
first active-set solve, the *next* one, a different case on the same model (K0 and
deconfinement changed, as in a sweep), and an Uzawa solve; the ratios
(factorization + contact) / floor from the least of each timing, and their median over
the repeats (each repeat times the floor and the solve back to back); and the whole
``run_case``. All timings of one size come from the same run.

    python -m bench.solver [--json] [--sizes h:far,h:far,...] [--repeat N]
"""

from __future__ import annotations

if __name__ == "__main__":
    from bench import one_blas_thread

    one_blas_thread()

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from bench import print_rows  # noqa: E402
from solver import CaseSpec, run_case  # noqa: E402
from solver.fe.linalg import InterfaceFactor  # noqa: E402
from solver.model import TunnelModel  # noqa: E402
import solver.stages.loads as stage_fns

SIZES = [(0.1, 4.0), (0.05, 2.0), (0.025, 1.0)]


def _floor(model: TunnelModel) -> float:
    factors = []  # freed after the timing, as the model's factors are (about 6 ms at 152k DOF)
    t0 = time.perf_counter()
    for fb in (model.ground, model.lining):
        K, order = fb.matrix()  # what the model factorizes and its ordering, nothing ordered last
        factors.append(InterfaceFactor(K, np.array([], dtype=np.int64), order))
        factors[-1].solve(np.ones(K.shape[0]))
    return time.perf_counter() - t0


#: Cases of the "next" solves: K0 and deconfinement of the default case changed, as in a sweep.
NEXT = [(0.7, 0.3), (0.5, 0.6), (1.0, 0.0), (0.3, 0.45)]


def _variant(spec: CaseSpec, k0: float, deconfinement: float) -> CaseSpec:
    return spec.model_copy(update={
        "loads": spec.loads.model_copy(update={"lateral_ratio": k0}),
        "excavation": spec.excavation.model_copy(update={"deconfinement": deconfinement})})


def _ratios(t: dict[str, float]) -> dict[str, float]:
    """(factorization + contact) / floor: a case alone (with the flexibility), a case on a
    built model, an Uzawa case on it."""
    fact, floor = t["factorization"], t["floor"]
    return {"first": (fact + t["flexibility"] + t["first_contact"]) / floor,
            "next": (fact + t["next_contact"]) / floor, "uzawa": (fact + t["uzawa_contact"]) / floor}


def bench_size(h: float, far: float, repeat: int) -> dict:
    """One mesh size; the factorization, the floor and the contact solves are each timed
    ``repeat`` times, alternating, and the least of each is reported."""
    spec = CaseSpec(mesh=dict(interface_size=h, far_size=far))
    model = TunnelModel(spec)
    row = {"interface_size": h, "far_size": far, "dof": model.ground.body.n + model.lining.body.n,
           "interface_nodes": model.m, "mesh_s": model.timings["mesh"], "assembly_s": model.timings["assembly"]}
    t0 = time.perf_counter()
    stage_fns.stage_loads(model, spec)  # load shapes: assembled once per model, as in a sweep
    row["stage_loads_s"] = time.perf_counter() - t0
    uzawa = spec.model_copy(update={"solver": spec.solver.model_copy(update={"inner": "uzawa"})})
    best: dict[str, float] = {}
    per_repeat = []
    for _ in range(repeat):
        times = {"floor": _floor(model)}
        model.drop_factorizations()
        model.S_normal  # noqa: B018 -- factorization: timed inside the model
        times["factorization"] = model.timings["factorization"]
        times["flexibility"] = model.timings["flexibility"]
        model.kept.forget()  # each round solves its cases, none taken from the last round
        t0 = time.perf_counter()
        first = model.solve(spec)
        times["first_contact"] = time.perf_counter() - t0
        for i, (k0, ld) in enumerate(NEXT):
            t0 = time.perf_counter()
            model.solve(_variant(spec, k0, ld))
            times[f"next{i}"] = time.perf_counter() - t0
        times["next_contact"] = float(np.median([times.pop(f"next{i}") for i in range(len(NEXT))]))
        t0 = time.perf_counter()
        slow = model.solve(uzawa)
        times["uzawa_contact"] = time.perf_counter() - t0
        best = {k: min(v, best.get(k, np.inf)) for k, v in times.items()}
        per_repeat.append(_ratios(times))
    row.update({f"{k}_s": v for k, v in best.items()})
    row["active_set_iterations"], row["uzawa_iterations"] = first.iterations, slow.iterations
    row.update({f"{k}_ratio": v for k, v in _ratios(best).items()})
    # the same ratios within each repeat (floor and solve timed back to back), median
    row.update({f"{k}_ratio_median": float(np.median([r[k] for r in per_repeat])) for k in ("first", "next")})
    t0 = time.perf_counter()
    ds = run_case(spec)
    row["run_case_s"] = time.perf_counter() - t0
    row["max_abs_moment_kNm"] = float(ds.max_abs_moment) / 1e3
    return row


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--sizes", default=",".join(f"{h}:{f}" for h, f in SIZES))
    ap.add_argument("--repeat", type=int, default=3, help="timings per size (the least is reported)")
    args = ap.parse_args(argv)
    rows = [bench_size(*map(float, s.split(":")), repeat=args.repeat) for s in args.sizes.split(",")]
    print_rows(rows, as_json=args.json)


if __name__ == "__main__":
    main()
