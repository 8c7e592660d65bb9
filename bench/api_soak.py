"""The API's memory under a long mixed load: does its resident memory level off? (issue 38, item 12)

``python -m bench.api_soak [--minutes 16] [--clients 3] [--json]``: the deployment's topology on
loopback (a ``dask scheduler``, two workers, the API as its own process), then ``--clients`` threads
of mixed traffic for ``--minutes``: new coarse cases (``POST /cases``) and small sweeps
(``POST /sweeps``), reading them back (``GET /cases/{id}``, the case page, a figure, the sweep's table
and CSV), the dashboard, the lists and ``/health``. Every 20 s the API process's RSS (psutil) is
sampled with the requests and errors so far. Reported: the RSS after the first two minutes (warm-up:
imports, first figures), its least-squares growth in MB a minute over the rest and over its first and
second halves, and the largest RSS. A leak grows at the same rate in both halves; memory that levels off grows in the first
and not the second.
"""
from __future__ import annotations

import argparse
import json
import random
import tempfile
import threading
import time
from pathlib import Path

import httpx
import psutil

from service.process import running_cluster, running_service

SAMPLE_EVERY = 20.0
WARM_UP = 120.0


def _case(i: int) -> dict:
    return {"mesh": {"interface_size": 0.25, "far_size": 8.0}, "loads": {"surface_load": 2.0e4 + 7.0 * i}}


def _sweep(i: int) -> dict:
    return {"name": f"soak-{i}", "base": {"mesh": {"interface_size": 0.25, "far_size": 8.0}},
            "vary": {"loads.lateral_ratio": [0.45 + 0.001 * i, 0.6 + 0.001 * i, 0.75 + 0.001 * i]}}


def _traffic(url: str, seed: int, until: float, counts: dict, lock: threading.Lock) -> None:
    """One client's mixed requests until ``until`` (monotonic)."""
    rng = random.Random(seed)
    cases, sweeps = [], []
    with httpx.Client(base_url=url, timeout=60) as http:
        i = seed * 1_000_000
        while time.monotonic() < until:
            r = rng.random()
            try:
                if r < 0.15:
                    i += 1
                    answer = http.post("/cases", json=_case(i))
                    if answer.status_code in (200, 201, 202):
                        cases.append(answer.json()["id"])
                elif r < 0.18:
                    i += 1
                    answer = http.post("/sweeps", json=_sweep(i))
                    if answer.status_code in (200, 201, 202):
                        sweeps.append(answer.json()["id"])
                elif r < 0.45 and cases:
                    answer = http.get(f"/cases/{rng.choice(cases)}")
                elif r < 0.55 and cases:
                    answer = http.get(f"/ui/cases/{rng.choice(cases)}")
                elif r < 0.62 and cases:
                    answer = http.get(f"/cases/{rng.choice(cases)}/plots/contact_pressure.png")
                elif r < 0.70 and sweeps:
                    answer = http.get(f"/sweeps/{rng.choice(sweeps)}/table")
                elif r < 0.75 and sweeps:
                    answer = http.get(f"/sweeps/{rng.choice(sweeps)}/summary.csv")
                elif r < 0.85:
                    answer = http.get(rng.choice(["/", "/sweeps", "/cases?limit=20"]))
                else:
                    answer = http.get("/health")
                bad = answer.status_code >= 500
            except httpx.HTTPError:
                bad = True
            with lock:
                counts["requests"] += 1
                counts["errors"] += int(bad)
            time.sleep(0.02)


def _api_process(url: str) -> psutil.Process:
    """The process serving ``url`` (a child of this one, listening on its port)."""
    port = int(url.rsplit(":", 1)[1])
    for child in psutil.Process().children(recursive=True):
        try:
            if any(c.laddr and c.laddr.port == port and c.status == psutil.CONN_LISTEN
                   for c in child.net_connections(kind="tcp")):
                return child
        except (psutil.AccessDenied, psutil.NoSuchProcess):
            continue
    raise RuntimeError(f"no process of ours listens on port {port}")


def soak(minutes: float, clients: int) -> dict:
    with tempfile.TemporaryDirectory(prefix="bench-api-soak-") as root, running_cluster(2) as scheduler, \
            running_service(Path(root) / "results", scheduler=scheduler, workers=2) as url:
        api = _api_process(url)
        counts, lock = {"requests": 0, "errors": 0}, threading.Lock()
        start = time.monotonic()
        until = start + 60.0 * minutes
        threads = [threading.Thread(target=_traffic, args=(url, k + 1, until, counts, lock), daemon=True)
                   for k in range(clients)]
        for t in threads:
            t.start()
        samples = []
        while time.monotonic() < until:
            time.sleep(SAMPLE_EVERY)
            with lock:
                samples.append({"seconds": round(time.monotonic() - start, 1), "rss_mb": api.memory_info().rss / 2**20,
                                **counts})
        for t in threads:
            t.join()
    return {"minutes": minutes, "clients": clients, "samples": samples, **_growth(samples)}


def _growth(samples: list[dict]) -> dict:
    """RSS after the warm-up, its least-squares growth (MB a minute) over all the samples after it and
    over their two halves (RSS moves by several MB between samples: endpoints alone would be noise),
    and the largest RSS."""
    import numpy as np

    after = [s for s in samples if s["seconds"] >= WARM_UP]
    if len(after) < 6:
        return {}
    t = np.array([s["seconds"] for s in after]) / 60.0
    rss = np.array([s["rss_mb"] for s in after])
    half = len(after) // 2
    slope = lambda a, b: float(np.polyfit(t[a:b], rss[a:b], 1)[0])  # noqa: E731
    return {"rss_after_warm_up_mb": float(rss[0]), "mb_per_min": slope(0, None),
            "first_half_mb_per_min": slope(0, half), "second_half_mb_per_min": slope(half, None),
            "rss_range_mb": [float(rss.min()), float(rss.max())], "max_rss_mb": max(s["rss_mb"] for s in samples),
            "requests": samples[-1]["requests"], "errors": samples[-1]["errors"]}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.api_soak", description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=16.0)
    parser.add_argument("--clients", type=int, default=3)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    report = soak(args.minutes, args.clients)
    if args.json:
        print(json.dumps(report, indent=1))
        return 0
    for s in report["samples"]:
        print(f"{s['seconds']:7.0f} s  RSS {s['rss_mb']:7.1f} MB  requests {s['requests']:6d}  errors {s['errors']}")
    if "first_half_mb_per_min" in report:
        print(f"after the warm-up: RSS {report['rss_after_warm_up_mb']:.1f} MB, growth {report['mb_per_min']:.2f} "
              f"MB/min ({report['first_half_mb_per_min']:.2f} then {report['second_half_mb_per_min']:.2f}); "
              f"largest {report['max_rss_mb']:.1f} MB; {report['requests']} requests, {report['errors']} errors")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
