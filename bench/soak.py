"""Worker memory over a long run of cases: is it a leak or the allocator?

``python -m bench.soak [--cases N] [--workers W] [--every K] [--json]``: N distinct cases
(half share one model and vary the loads, half change the ground's stiffness and so build
a model of their own, as a service's mixed traffic does) are stored on an embedded
LocalCluster of W worker processes, in chunks of K. After each chunk every worker
reports its resident memory (RSS), what glibc's heap holds (``mallinfo2``: bytes in use
and free bytes kept in the arenas), the live Python objects' memory (``tracemalloc`` is
too slow for this; the count of the models it keeps stands in) and the number of
models cached. A leak shows as heap *in use* growing with the cases; fragmentation or
retention as *free* bytes kept growing while in use stays flat.
"""
from __future__ import annotations

import argparse
import json
import tempfile
import time


def worker_memory() -> dict:
    """RSS, glibc heap in use / kept free, and cached models of this process (bytes, count)."""
    import psutil

    from solver.model import _SHARED
    from workflows.workers import heap_stats

    heap = heap_stats()
    return {"rss": psutil.Process().memory_info().rss, "heap_in_use": heap.get("in_use", 0),
            "heap_free": heap.get("free", 0), "models": len(_SHARED)}


def soak(n_cases: int, n_workers: int, every: int) -> list[dict]:
    from distributed import wait

    from solver.spec import CaseSpec
    from workflows.sweep import local_client
    from workflows.tasks import map_cases

    samples = []
    with tempfile.TemporaryDirectory(prefix="bench-soak-") as root, local_client(n_workers) as client:
        start = time.perf_counter()
        for chunk in range(0, n_cases, every):
            specs = []
            for k in range(chunk, min(n_cases, chunk + every)):
                if k % 2:
                    spec = {"loads": {"surface_load": 1e3 * k}}
                else:
                    spec = {"ground": {"young": 4e7 + 1e3 * k}}
                specs.append(CaseSpec.model_validate(spec))
            futures = map_cases(client, [s.canonical_json() for s in specs], [s.case_id for s in specs], root)
            wait(futures)
            failed = [f.result()["error"] for f in futures if f.result()["status"] != "done"]
            if failed:
                raise RuntimeError(failed[0])
            del futures
            for worker, memory in sorted(client.run(worker_memory).items()):
                samples.append({"cases": chunk + len(specs), "seconds": time.perf_counter() - start,
                                "worker": worker, **memory})
            last = samples[-n_workers:]
            print(f"{chunk + len(specs):6d} cases {last[0]['seconds']:6.0f} s  " + "  ".join(
                f"rss {m['rss'] / 2**20:6.0f} MiB (heap used {m['heap_in_use'] / 2**20:5.0f}, "
                f"free {m['heap_free'] / 2**20:5.0f}, models {m['models']})" for m in last), flush=True)
    return samples


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=2000)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--every", type=int, default=100)
    parser.add_argument("--json", action="store_true", help="print the samples as JSON at the end")
    args = parser.parse_args(argv)
    samples = soak(args.cases, args.workers, args.every)
    if args.json:
        print(json.dumps(samples))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
