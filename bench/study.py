"""A sampled study end to end (SPEC §8, issue 27): a Sobol' sweep of the default geometry over
K0, λd, the ground's stiffness and the load factor, solved on a local dask cluster (two worker
processes, one thread each) into a fresh result store, then the sensitivity of the moment and
of the utilization and the probability that the section fails.

    python -m bench.study [--samples 1024] [--workers 2] [--json]
    python -m bench.study --reliability form,subset,ak-mcs [--beta 3.8] [--workers 2] [--json]

``--reliability``: the cost of each method of SPEC §9.6 on the exact limit state of issue 41
(:mod:`bench.exact_limit_state`: FE cases on a coarse mesh, surface load and γF lognormal, the
exact β by quadrature): FE calls, minutes, β found against the exact one.

Every case has its own ground stiffness; they still share one model per worker: the ground's
stiffness is linear in its modulus, so a case solves on the model's factorization with K⁺
scaled (:class:`solver.fe.flexibility.ScaledBody`). 2026-11-25, two cores: 227 s before that
reuse (every case built its own model), 61 s with it.
"""
from __future__ import annotations

import argparse
import json
import tempfile
import time

VARY = {"loads.lateral_ratio": {"distribution": "uniform", "low": 0.4, "high": 1.0},
        "excavation.deconfinement": {"distribution": "uniform", "low": 0.2, "high": 0.6},
        "ground.young": {"distribution": "lognormal", "mean": 5.0e7, "std": 1.5e7},
        "design.load_factor": {"distribution": "lognormal", "mean": 1.35, "std": 0.15}}


def main(argv=None) -> None:
    from workflows import run_sweep
    from workflows.studies import reliability, sensitivity
    from workflows.sweep import local_client

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=1024)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--reliability", metavar="METHODS", help="comma-separated: form, subset, ak-mcs")
    ap.add_argument("--beta", type=float, default=3.8, help="the exact β of the --reliability study")
    args = ap.parse_args(argv)
    if args.reliability:
        return reliability_cost(args.reliability.split(","), args.beta, args.workers, as_json=args.json)
    sweep = {"name": "bench study", "mode": "sobol", "samples": args.samples, "seed": 1, "vary": VARY}
    with tempfile.TemporaryDirectory() as root, local_client(args.workers) as client:
        client.run(lambda: None)  # the workers are up before the clock starts
        t0 = time.perf_counter()
        ids = run_sweep(sweep, root, client)
        t1 = time.perf_counter()
        moment = sensitivity(root, ids, "max_abs_moment")
        utilization = sensitivity(root, ids, "max_utilization")
        failure = reliability(root, ids)
        t2 = time.perf_counter()
    out = {"cases": len(ids), "solve_and_store_s": t1 - t0, "cases_per_minute": 60 * len(ids) / (t1 - t0),
           "sensitivity_and_reliability_s": t2 - t1, "total_s": t2 - t0,
           "moment_total_order": dict(zip(map(str, moment["parameter"].values),
                                          map(float, moment["total_order"].values))),
           "utilization_total_order": dict(zip(map(str, utilization["parameter"].values),
                                               map(float, utilization["total_order"].values))),
           "probability_of_failure": [failure["probability"], failure["ci_low"], failure["ci_high"]]}
    if args.json:
        print(json.dumps(out, indent=2))
        return
    print(f"{out['cases']} cases solved and stored in {out['solve_and_store_s']:.1f} s "
          f"({out['cases_per_minute']:.0f} a minute); two sensitivities and the reliability in "
          f"{out['sensitivity_and_reliability_s']:.1f} s; total {out['total_s']:.1f} s")
    for what in ("moment_total_order", "utilization_total_order"):
        print(what, {k: round(v, 3) for k, v in out[what].items()})
    print("P(max_utilization > 1) = {:.4f} [{:.4f}, {:.4f}]".format(*out["probability_of_failure"]))



#: Budgets of the --reliability runs (the tests' ceilings for β 3.8).
BUDGETS = {"form": 300, "subset": 3000, "ak-mcs": 300}


def reliability_cost(methods: list[str], beta: float, workers: int, *, as_json: bool = False) -> None:
    """FE calls and minutes of each reliability method on the exact limit state at ``beta``."""
    from scipy import stats

    from bench.exact_limit_state import ExactLimitState
    from workflows import reliability_study
    from workflows.sweep import local_client

    exact = ExactLimitState()
    rows = []
    with tempfile.TemporaryDirectory() as root, local_client(workers) as client:
        client.run(lambda: None)
        for method in methods:
            study = exact.study(beta, method, BUDGETS[method])
            truth = float(-stats.norm.ppf(exact.probability(study)))
            t0 = time.perf_counter()
            r = reliability_study(study, root, client)
            minutes = (time.perf_counter() - t0) / 60
            rows.append({"method": method, "calls": r["calls"], "minutes": minutes, "beta": r["beta"],
                         "beta_ci": r["beta_ci"], "exact_beta": truth, "converged": r["converged"]})
    if as_json:
        print(json.dumps(rows, indent=2))
        return
    print(f"{'method':<8} {'calls':>6} {'minutes':>8} {'beta':>7} {'95 % interval':>17} {'exact':>7}")
    for row in rows:
        ci = row["beta_ci"] or [None, None]
        shown = "-" if None in ci else f"{ci[0]:.3f}-{ci[1]:.3f}"
        beta_found = "-" if row["beta"] is None else f"{row['beta']:.3f}"
        print(f"{row['method']:<8} {row['calls']:>6} {row['minutes']:>8.2f} {beta_found:>7} {shown:>17} "
              f"{row['exact_beta']:>7.3f}")


if __name__ == "__main__":
    main()
