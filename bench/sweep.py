"""Sweep throughput on one and on two dask worker processes.

``python -m bench.sweep [--json] [--cases N] [--reuse | --per-case | --idle]``: the same sweep of N default-size cases
(lining thickness varied) is solved into a fresh result folder on an embedded
LocalCluster with 1 and then 2 worker processes (one thread each). Cluster start-up
and worker warm-up (imports, one coarse case stored) are excluded from the timings. Each
configuration runs ``--repeat`` times (alternating 1 and 2 workers) and the best
run counts, which damps noise from other work on a shared machine. Reports
cases/minute and the parallel efficiency rate2 / (2 rate1).
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from contextlib import nullcontext

import numpy as np


def _warm_up(spec_json: str | None = None) -> None:
    """Bring a worker to its steady state before the clock starts: imports, gmsh, and the
    first netCDF write (xarray finds its backends and HDF5 starts up: about 0.4 s once
    per process) by storing one coarse case (or ``spec_json``'s, whose model the worker then
    holds) into a throw-away folder."""
    import solver
    from workflows.result_store import ResultStore

    spec = solver.CaseSpec.model_validate_json(spec_json) if spec_json else \
        solver.CaseSpec.model_validate({"mesh": {"interface_size": 0.5, "far_size": 8.0}})
    with tempfile.TemporaryDirectory(prefix="bench-warm-up-") as root:
        ResultStore(root).run_and_store(spec)


def measure(n_workers: int, cases: int) -> dict:
    """Solve the benchmark sweep on ``n_workers`` processes; return timings."""
    from workflows.sweep import Sweep, local_client, run_sweep

    thicknesses = [round(float(t), 4) for t in np.linspace(0.2, 0.45, cases)]
    sweep = Sweep(name=f"bench-{n_workers}", vary={"lining.thickness": thicknesses})
    statuses = []
    with tempfile.TemporaryDirectory(prefix="bench-sweep-") as root, local_client(n_workers) as client:
        client.run(_warm_up)
        start = time.perf_counter()
        run_sweep(sweep, root, client=client, on_result=statuses.append)
        seconds = time.perf_counter() - start
    failed = sum(s["status"] != "done" for s in statuses)
    solve = [s["summary"].get("solve_seconds", np.nan) for s in statuses]
    return {"workers": n_workers, "cases": cases, "failed": failed, "seconds": seconds,
            "cases_per_minute": 60.0 * cases / seconds, "mean_solve_seconds": float(np.nanmean(solve))}


def reuse(cases_k0: int = 20, cases_ld: int = 10, mixed: int = 64, n_workers: int = 2) -> dict:
    """Cases/minute with models shared per worker against every case built from nothing.

    The K0 × deconfinement sweep on the default geometry (cases_k0 × cases_ld cases) and a
    mixed sweep (thickness × ground stiffness × K0, ``mixed`` cases, every geometry/material
    pair different four times over), each run with ``TUNNEL_CONTACT_SHARED_MODELS`` = 2 (the
    default: reuse) and = 0 (the path before reuse), alternating, into fresh folders.
    """
    from workflows.sweep import Sweep, local_client, run_sweep

    sweeps = {
        "k0-deconfinement": Sweep(name="k0-ld", vary={
            "loads.lateral_ratio": [round(float(k), 4) for k in np.linspace(0.4, 1.3, cases_k0)],
            "excavation.deconfinement": [round(float(x), 4) for x in np.linspace(0.0, 0.6, cases_ld)]}),
        "mixed": Sweep(name="mixed", vary={
            "geometry.thickness": [0.25, 0.3, 0.35, 0.4], "ground.young": [2e7, 5e7, 1e8, 2e8],
            "loads.lateral_ratio": [0.5, 0.7, 0.9, 1.1][: max(1, mixed // 16)]}),
    }
    out = {}
    for name, sweep in sweeps.items():
        for label, shared in (("shared", "2"), ("alone", "0")):
            os.environ["TUNNEL_CONTACT_SHARED_MODELS"] = shared
            with tempfile.TemporaryDirectory(prefix="bench-reuse-") as root, local_client(n_workers) as client:
                client.run(_warm_up)
                start = time.perf_counter()
                ids = run_sweep(sweep, root, client=client)
                seconds = time.perf_counter() - start
            out[f"{name}_{label}"] = {"cases": len(ids), "seconds": seconds,
                                      "cases_per_minute": 60.0 * len(ids) / seconds}
        out[f"{name}_speedup"] = out[f"{name}_shared"]["cases_per_minute"] / out[f"{name}_alone"]["cases_per_minute"]
    os.environ.pop("TUNNEL_CONTACT_SHARED_MODELS", None)
    return out


#: the coarse mesh of the write-path figures (issue 38, item 13)
COARSE_MESH = {"interface_size": 0.25, "far_size": 8.0}


def _k0_ld(n: int, base: dict | None = None):
    """A K0 × deconfinement grid of about ``n`` cases (40 K0 values) on ``base``."""
    from workflows.sweep import Sweep

    k0s = [round(float(k), 4) for k in np.linspace(0.4, 1.3, 40)]
    lds = [round(float(x), 4) for x in np.linspace(0.0, 0.6, max(1, n // 40))]
    return Sweep(name="k0-ld", base=base or {}, vary={"loads.lateral_ratio": k0s, "excavation.deconfinement": lds})


def write_path(cases: int = 1000) -> dict:
    """Cases/minute of a K0 × deconfinement sweep on two workers (models shared) against the rate of
    solving and storing the same cases in this process, for the coarse mesh and the default one
    (the default with a fifth of the cases); efficiency = the sweep's rate / (2 × in-process rate).
    As the in-process rate is measured on a built model, the workers hold theirs before the clock
    starts (the steady state); the same sweep with each worker building its model on its first case
    is reported beside it (``..._building_models``: one build per worker, 0.1 s coarse, 0.2 s default)."""
    from workflows.result_store import ResultStore
    from workflows.sweep import expand_sweep, local_client, run_sweep

    out = {}
    for label, base, n in (("coarse", {"mesh": COARSE_MESH}, cases), ("default", {}, max(40, cases // 5))):
        sweep = _k0_ld(n, base)
        specs = expand_sweep(sweep)[:100]
        with tempfile.TemporaryDirectory(prefix="bench-write-path-") as root:
            store = ResultStore(root)
            store.run_and_store(specs[0])  # the model built
            start = time.perf_counter()
            for spec in specs[1:]:
                store.run_and_store(spec)
            alone = (len(specs) - 1) / (time.perf_counter() - start) * 60.0
        rates = {}
        for warm in ("built", "cold"):  # each worker's model built before the clock starts, or not
            with tempfile.TemporaryDirectory(prefix="bench-write-path-") as root, local_client(2) as client:
                client.run(_warm_up, specs[0].named_json() if warm == "built" else None)
                start = time.perf_counter()
                ids = run_sweep(sweep, root, client=client)
                rates[warm] = 60.0 * len(ids) / (time.perf_counter() - start)
        rate = rates["built"]
        out[label] = {"cases": len(ids), "two_workers_cases_per_minute": rate,
                      "in_process_cases_per_minute": alone, "efficiency": rate / (2.0 * alone),
                      "two_workers_building_models_cases_per_minute": rates["cold"],
                      "efficiency_building_models": rates["cold"] / (2.0 * alone)}
    return out


def _store_cases(n: int) -> list[float]:
    """Seconds to solve and store each of ``n`` default cases (K0 varied) on one shared model,
    the first (which builds the model) excluded."""
    from solver import CaseSpec
    from workflows.result_store import ResultStore

    seconds = []
    with tempfile.TemporaryDirectory(prefix="bench-per-case-") as root:
        store = ResultStore(root)
        for k0 in np.linspace(0.4, 1.2, n + 1):
            start = time.perf_counter()
            store.run_and_store(CaseSpec.model_validate({"loads": {"lateral_ratio": round(float(k0), 4)}}))
            seconds.append(time.perf_counter() - start)
    return seconds[1:]


def per_case(n: int = 30) -> dict:
    """Median ms to store a default case on a shared model: in this process, in a dask worker
    started with dask's own environment (``MALLOC_TRIM_THRESHOLD_`` alone), and in one
    started with :data:`workflows.workers.WORKER_ENVIRON`."""
    import dask
    from distributed import Client, LocalCluster

    from workflows.sweep import local_client
    from workflows.workers import WORKER_ENVIRON

    for name in WORKER_ENVIRON:  # a nanny copies them into this process; start clean
        os.environ.pop(name, None)
    out = {"plain_process_ms": 1e3 * float(np.median(_store_cases(n)))}
    with dask.config.set({"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": 65536}), \
            LocalCluster(n_workers=1, threads_per_worker=1, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        out["worker_dask_default_ms"] = 1e3 * float(np.median(client.submit(_store_cases, n, pure=False).result()))
    for name in WORKER_ENVIRON:
        os.environ.pop(name, None)
    with local_client(1) as client:
        out["worker_ms"] = 1e3 * float(np.median(client.submit(_store_cases, n, pure=False).result()))
    return out


def idle(seconds: float = 10.0, n_workers: int = 2) -> dict:
    """CPU seconds the cluster's processes spend doing nothing for ``seconds``: the
    process holding the scheduler and the nannies, and each worker, with dask's defaults
    and with :data:`workflows.workers.CLUSTER_CONFIG`, alternating, twice."""
    import psutil
    from distributed import Client, LocalCluster

    from workflows.workers import worker_config

    def cpu(process) -> float:
        return sum(process.cpu_times()[:2])

    out: dict[str, list] = {"dask_defaults": [], "ours": []}
    for _ in range(2):
        for label, config in (("dask_defaults", nullcontext), ("ours", worker_config)):
            with config(), LocalCluster(n_workers=n_workers, threads_per_worker=1, dashboard_address=None) as cluster, \
                    Client(cluster):
                time.sleep(2.0)  # start-up done
                me = psutil.Process()
                workers = [c for c in me.children(recursive=True) if "resource_tracker" not in " ".join(c.cmdline())]
                before = [cpu(me)] + [cpu(w) for w in workers]
                time.sleep(seconds)
                after = [cpu(me)] + [cpu(w) for w in workers]
            spent = [round(b - a, 3) for a, b in zip(before, after)]
            out[label].append({"scheduler_and_nannies_s": spent[0], "workers_s": spent[1:]})
    out["seconds"] = seconds
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.sweep", description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--cases", type=int, default=8, help="cases in the sweep (default 8)")
    parser.add_argument("--repeat", type=int, default=3, help="runs per configuration; the best counts")
    parser.add_argument("--reuse", action="store_true",
                        help="models shared per worker vs every case alone (200-case K0 x deconfinement, 64 mixed)")
    parser.add_argument("--idle", action="store_true",
                        help="CPU seconds an idle two-worker cluster spends in 10 s: dask's defaults vs ours")
    parser.add_argument("--write-path", type=int, default=0, metavar="N",
                        help="an N-case coarse and an N/5-case default sweep on two workers against "
                             "in-process solve-and-store (issue 38, item 13)")
    parser.add_argument("--per-case", action="store_true",
                        help="ms to store one case on a shared model: plain process, worker with dask's "
                             "malloc setting, worker with ours")
    args = parser.parse_args(argv)
    if args.per_case:
        print(json.dumps(per_case(), indent=1))
        return 0
    if args.write_path:
        print(json.dumps(write_path(args.write_path), indent=1))
        return 0
    if args.idle:
        print(json.dumps(idle(), indent=1))
        return 0
    if args.reuse:
        print(json.dumps(reuse(), indent=1))
        return 0
    from workflows.commands import configure_logging

    configure_logging()
    load_before = os.getloadavg()
    runs: dict[int, list[dict]] = {1: [], 2: []}
    for _ in range(max(1, args.repeat)):
        for n in (1, 2):
            runs[n].append(measure(n, args.cases))
    one, two = (min(runs[n], key=lambda r: r["seconds"]) for n in (1, 2))
    for best, n in ((one, 1), (two, 2)):
        best["all_seconds"] = [round(r["seconds"], 3) for r in runs[n]]
    report = {"cpu_count": os.cpu_count(), "load_average_before": load_before,
              "one_worker": one, "two_workers": two,
              "efficiency": two["cases_per_minute"] / (2.0 * one["cases_per_minute"])}
    if args.json:
        print(json.dumps(report, indent=1))
    else:
        for r in (one, two):
            print(f"{r['workers']} worker(s): {r['cases']} cases in {r['seconds']:.2f} s = "
                  f"{r['cases_per_minute']:.1f} cases/min (mean solve {r['mean_solve_seconds']:.2f} s, "
                  f"{r['failed']} failed; runs {r['all_seconds']} s)")
        print(f"efficiency rate2 / (2 rate1) = {report['efficiency']:.2f} on {report['cpu_count']} CPUs "
              f"(load average before: {report['load_average_before'][0]:.2f})")
    return 0 if all(r["failed"] == 0 for n in runs for r in runs[n]) else 1


if __name__ == "__main__":
    sys.exit(main())
