"""Interface-model benchmark: the default case per ``interface.model`` (SPEC §1.2).

One :class:`~solver.model.TunnelModel` serves every interface model (they share its
``model_key``); per model: seconds of ``model.solve`` (contact stage: interface solve,
bolt search, displacement recovery, KKT check), of the interface solve alone
(``Solution.timings["contact"]``), iterations, bolt trials, slipping nodes, KKT residual,
and the seconds of a full ``run_case`` (mesh, assembly, factorization, solve, Dataset).
Times are the best of ``--repeat`` runs (the machine may be shared); the ratio is
against ``frictionless``. On a shared, oversubscribed machine multithreaded OpenBLAS
makes small dense solves erratic (10-100x slower); ``OPENBLAS_NUM_THREADS=1`` gives
stable figures.

    OPENBLAS_NUM_THREADS=1 python -m bench.interfaces [--json] [--repeat N]
"""
from __future__ import annotations

import argparse
import json
import time

from solver import CaseSpec, run_case
from solver.model import TunnelModel

MODELS = [("frictionless", 0.0), ("coulomb", 0.3), ("coulomb", 0.6), ("bonded", 0.0)]


def case(model: str, friction: float) -> CaseSpec:
    return CaseSpec(interface=dict(model=model, friction=friction))


def bench(repeat: int = 3) -> dict:
    t0 = time.perf_counter()
    tunnel = TunnelModel(case("frictionless", 0.0))
    build = time.perf_counter() - t0
    rows = []
    for name, mu in MODELS:
        spec = case(name, mu)
        solve_s, contact_s = [], []
        for _ in range(repeat):
            tunnel.kept.forget()  # solved each time, not taken from the last
            t0 = time.perf_counter()
            sol = tunnel.solve(spec)
            solve_s.append(time.perf_counter() - t0)
            contact_s.append(sol.timings["contact"])
        full = []
        for _ in range(repeat):
            t0 = time.perf_counter()
            run_case(spec)
            full.append(time.perf_counter() - t0)
        rows.append({"interface": name, "friction": mu, "solve_s": min(solve_s), "contact_s": min(contact_s),
                     "run_case_s": min(full), "iterations": sol.iterations, "bolt_trials": len(sol.trials),
                     "slipping": int(sol.slipping.sum()), "kkt_residual": sol.kkt_residual})
    ref = rows[0]["solve_s"]
    for row in rows:
        row["ratio"] = row["solve_s"] / ref
    return {"interface_nodes": tunnel.m, "build_s": build, "rows": rows}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    out = bench(args.repeat)
    if args.json:
        print(json.dumps(out, indent=2))
        return
    print(f"default case, {out['interface_nodes']} interface nodes; TunnelModel built in {out['build_s']:.2f} s")
    print(f"{'interface':<13}{'mu':>5}{'solve s':>9}{'contact s':>11}{'ratio':>7}{'run_case s':>12}"
          f"{'iter':>6}{'bolts':>6}{'slip':>6}{'kkt':>10}")
    for r in out["rows"]:
        print(f"{r['interface']:<13}{r['friction']:>5.2g}{r['solve_s']:>9.3f}{r['contact_s']:>11.3f}{r['ratio']:>7.2f}"
              f"{r['run_case_s']:>12.2f}{r['iterations']:>6}{r['bolt_trials']:>6}{r['slipping']:>6}"
              f"{r['kkt_residual']:>10.1e}")


if __name__ == "__main__":
    main()
