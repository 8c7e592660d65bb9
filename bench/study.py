"""A sampled study end to end (SPEC §8, issue 27): a Sobol' sweep of the default geometry over
K0, λd, the ground's stiffness and the load factor, solved on a local dask cluster (two worker
processes, one thread each) into a fresh result store, then the sensitivity of the moment and
of the utilization and the probability that the section fails.

    python -m bench.study [--samples 1024] [--workers 2] [--json]

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
    args = ap.parse_args(argv)
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


if __name__ == "__main__":
    main()
