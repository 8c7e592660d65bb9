"""Service benchmark: request latency while the workers are busy solving.

Starts the deployment's topology on loopback (a ``dask scheduler``, two single-threaded
``dask worker`` processes and the API), keeps the workers busy with a backlog of
cases, then has 20 concurrent clients (processes, one keep-alive connection each,
:class:`LightClient`: light, so the clients' own CPU does not show as server latency)
submit 200 distinct cases (``POST /cases``) and read each back (``GET /cases/{id}``).
Reports p50/p99/max latency of both and the error count (any non-2xx answer or
transport error). Target: p99 < 50 ms, no errors.

Then the bounded queue: the service runs with ``TUNNEL_CONTACT_MAX_OPEN_CASES`` = ``--max-open``
and the same clients keep submitting new cases until they are refused; reported are how many
cases were open at the first 429, how many submissions were accepted per second up to it, and
the latency of the 429 answers.

With ``--cpu``, only the API's CPU time per ``POST /cases`` and per ``GET /cases/{id}``
(one sequential client), over HTTP and with the app called in process through ASGI (no
server, no socket): the figures to compare code by, since the host's noise moves the
latencies above by a third from run to run.

    python -m bench.service [--json] [--clients 20] [--submissions 200] [--max-open 400] [--nice N] [--scheduler ADDR]
    python -m bench.service --cpu
"""
from __future__ import annotations

import argparse
import json
import socket
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from contextlib import ExitStack
from pathlib import Path
from typing import Optional
from urllib.parse import urlsplit

import httptools
import httpx
import numpy as np

from service.process import running_cluster, running_service

#: Cases that take a while on a worker (default mesh), to keep the workers busy.
BACKLOG = {"name": "bench-backlog", "base": {},
           "vary": {"loads.surface_load": [float(v) for v in np.linspace(5e4, 1.5e5, 16)]}}


def submission(i: int) -> dict:
    """The i-th benchmark case: coarse, distinct (so every POST creates a record and a task)."""
    return {"mesh": {"interface_size": 0.25, "far_size": 8.0},
            "loads": {"surface_load": 1.0e5 + 10.0 * i, "lateral_ratio": 0.45}}


class LightClient:
    """A keep-alive HTTP/1.1 connection whose own CPU stays out of the latencies measured.

    The 20 clients share this machine's two cores with the API and the workers, so every
    microsecond a client spends on a request is taken from the service. httpx spent about
    1 ms a request; ``http.client`` 0.42 ms per POST + GET pair; this client, which writes
    the request line and headers itself and parses the answer with ``httptools`` (the C
    parser uvicorn uses, already a dependency), 0.13 ms.
    """

    def __init__(self, url: str, timeout: float = 30.0):
        parts = urlsplit(url)
        self._host = f"{parts.hostname}:{parts.port}".encode()
        self._sock = socket.create_connection((parts.hostname, parts.port), timeout=timeout)
        self._sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._parser = httptools.HttpResponseParser(self)
        self._headers: dict[str, str] = {}
        self._body: list[bytes] = []
        self._complete = False

    # httptools callbacks
    def on_header(self, name: bytes, value: bytes) -> None:
        self._headers[name.decode("latin-1").lower()] = value.decode("latin-1")

    def on_body(self, body: bytes) -> None:
        self._body.append(body)

    def on_message_complete(self) -> None:
        self._complete = True

    def request(self, method: str, path: str, body: Optional[dict] = None) -> tuple[int, dict, bytes]:
        """Send one request; return status, lower-cased headers and body."""
        data = b"" if body is None else json.dumps(body).encode()
        self._sock.sendall(b"%s %s HTTP/1.1\r\nHost: %s\r\nContent-Type: application/json\r\n"
                           b"Content-Length: %d\r\n\r\n%s" % (method.encode(), path.encode(), self._host,
                                                                len(data), data))
        self._headers, self._body, self._complete = {}, [], False
        while not self._complete:
            chunk = self._sock.recv(65536)
            if not chunk:
                raise ConnectionError("the service closed the connection mid-answer")
            self._parser.feed_data(chunk)
        return self._parser.get_status_code(), self._headers, b"".join(self._body)

    def close(self) -> None:
        self._sock.close()


#: What a client counts as an error instead of an answer.
CLIENT_ERRORS = (OSError, httptools.HttpParserError)


def client_loop(client: LightClient, jobs: list[int], posts: list, gets: list, errors: list) -> None:
    """One client: submit its cases one after the other, reading each back."""
    for i in jobs:
        try:
            start = time.perf_counter()
            status, headers, _ = client.request("POST", "/cases", submission(i))
            posts.append(time.perf_counter() - start)
            if status != 202:
                errors.append(f"POST {status}")
                continue
            start = time.perf_counter()
            status, _, _ = client.request("GET", headers["location"])
            gets.append(time.perf_counter() - start)
            if status != 200:
                errors.append(f"GET {status}")
        except CLIENT_ERRORS as exc:
            errors.append(f"{type(exc).__name__}: {exc}")


def wait_busy(http: httpx.Client, workers: int, timeout: float = 60.0) -> None:
    """Wait until every worker is executing a case (they have imported the solver and run)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if http.get("/health").json()["running"] >= workers:
            return
        time.sleep(0.2)
    raise RuntimeError(f"workers not busy after {timeout} s")


def until_refused(client: LightClient, first: int, stride: int, accepted: list, refused: list,
                  errors: list, attempts: int = 400) -> None:
    """One client: submit new cases until it has been refused with 429 five times."""
    mine = 0
    for i in range(first, first + stride * attempts, stride):
        start = time.perf_counter()
        try:
            status, headers, _ = client.request("POST", "/cases", submission(i))
        except CLIENT_ERRORS as exc:
            errors.append(f"{type(exc).__name__}: {exc}")
            continue
        elapsed = time.perf_counter() - start
        if status == 202:
            accepted.append(time.perf_counter())
        elif status == 429 and "retry-after" in headers:
            refused.append((time.perf_counter(), elapsed))
            mine += 1
            if mine >= 5:
                return
        else:
            errors.append(f"POST {status}")


def saturate(url: str, clients: int, offset: int) -> dict:
    """Submit from ``clients`` threads until the service refuses with 429; where did it start?"""
    accepted: list[float] = []
    refused: list[tuple[float, float]] = []
    errors: list[str] = []
    with ExitStack() as stack:
        http = stack.enter_context(httpx.Client(base_url=url, timeout=30))
        pool = stack.enter_context(ThreadPoolExecutor(clients))
        each = [LightClient(url) for _ in range(clients)]
        for client in each:
            stack.callback(client.close)
        open_before = sum(http.get("/health").json()[k] for k in ("queued", "running"))
        start = time.perf_counter()
        list(pool.map(lambda k: until_refused(each[k], offset + k, clients, accepted, refused, errors),
                      range(clients)))
        health = http.get("/health").json()
    onset = min((t for t, _ in refused), default=None)
    before = [t for t in accepted if onset is None or t < onset]
    return {"open_before": open_before, "accepted": len(accepted), "accepted_before_first_429": len(before),
            "open_at_end": health["queued"] + health["running"],
            "accepted_per_s": len(before) / ((onset or time.perf_counter()) - start),
            "refused": [e for _, e in refused], "errors": errors}


def _process_client(url: str, jobs: list[int], warm: int, start_at: float) -> tuple[list, list, list]:
    """A client in its own process (no GIL shared with the others): warm up, wait for the
    common start time, then run :func:`client_loop`."""
    client = LightClient(url)
    try:
        client_loop(client, [warm], [], [], [])
        time.sleep(max(0.0, start_at - time.time()))
        posts: list[float] = []
        gets: list[float] = []
        errors: list[str] = []
        client_loop(client, jobs, posts, gets, errors)
    finally:
        client.close()
    return posts, gets, errors


def load(url: str, clients: int, submissions: int) -> dict:
    """Keep the workers busy, then run the load from ``clients`` processes (threads of one
    process would queue on its GIL, and their overhead would show as server latency);
    return latencies (s) and errors."""
    from concurrent.futures import ProcessPoolExecutor

    with ExitStack() as stack:
        http = stack.enter_context(httpx.Client(base_url=url, timeout=30))
        pool = stack.enter_context(ProcessPoolExecutor(clients))
        backlog = http.post("/sweeps", json=BACKLOG).raise_for_status().json()
        wait_busy(http, http.get("/health").json()["workers"])
        list(pool.map(int, range(clients)))  # start the processes before the clock
        busy_before = http.get("/health").json()
        start_at = time.time() + 3.0
        futures = [pool.submit(_process_client, url, list(range(k, submissions, clients)), submissions + k,
                               start_at) for k in range(clients)]
        results = [f.result() for f in futures]
        wall = time.time() - start_at
        busy_after = http.get("/health").json()
        backlog_state = http.get(f"/sweeps/{backlog['id']}").json()["counts"]
    posts = [x for r in results for x in r[0]]
    gets = [x for r in results for x in r[1]]
    errors = [x for r in results for x in r[2]]
    return {"posts": posts, "gets": gets, "errors": errors, "wall": wall,
            "busy_before": busy_before, "busy_after": busy_after, "backlog": backlog_state}


async def _cpu_per_request(request, cpu, requests: int, first: int) -> dict:
    """CPU milliseconds per ``POST /cases`` (a new case) and per ``GET /cases/{id}``: after
    100 warm-up posts, ``requests`` posts, then a read of each; ``request(method, path,
    body)`` (a coroutine) answers ``(status, headers)``, ``cpu()`` is the process's CPU
    seconds so far."""
    import asyncio

    for i in range(100):
        await request("POST", "/cases", submission(first + i))
    start = cpu()
    locations = []
    for i in range(requests):
        locations.append((await request("POST", "/cases", submission(first + 100 + i)))[1]["location"])
        if i % 20 == 19:
            await asyncio.sleep(0)  # in process: let the batches go to the scheduler, as a server would
    posted = cpu()
    for location in locations:
        await request("GET", location)
    got = cpu()
    return {"requests": requests, "post_cpu_ms": 1e3 * (posted - start) / requests,
            "get_cpu_ms": 1e3 * (got - posted) / requests}


def api_cpu(url: str, requests: int = 1500) -> dict:
    """:func:`_cpu_per_request` of the API process from one sequential client: a figure the
    host's noise leaves alone, unlike latency (CPU time of the process, read from the OS)."""
    import asyncio

    import psutil  # a dependency of distributed

    port = f"--port {urlsplit(url).port}"
    api = next(p for p in psutil.process_iter(["cmdline"])
               if "serve" in (p.info["cmdline"] or []) and port in " ".join(p.info["cmdline"] or []))
    client = LightClient(url)

    async def request(method: str, path: str, body: Optional[dict] = None) -> tuple[int, dict]:
        return client.request(method, path, body)[:2]

    try:
        return asyncio.run(_cpu_per_request(request, lambda: sum(api.cpu_times()[:2]), requests, 20 * requests))
    finally:
        client.close()


async def _asgi(app, method: str, path: str, body: Optional[dict] = None) -> tuple[int, dict]:
    """One request through the ASGI app itself (no server, no socket): status, headers."""
    import asyncio

    data = b"" if body is None else json.dumps(body).encode()
    scope = {"type": "http", "asgi": {"version": "3.0"}, "http_version": "1.1", "method": method,
             "scheme": "http", "path": path, "raw_path": path.encode(), "query_string": b"", "root_path": "",
             "headers": [(b"host", b"127.0.0.1"), (b"content-type", b"application/json"),
                         (b"content-length", str(len(data)).encode())],
             "client": ("127.0.0.1", 1), "server": ("127.0.0.1", 80)}
    messages = [{"type": "http.request", "body": data, "more_body": False}]
    answer: dict = {}

    async def receive() -> dict:
        if messages:
            return messages.pop()
        await asyncio.Event().wait()  # the client never disconnects
        return {}

    async def send(message: dict) -> None:
        if message["type"] == "http.response.start":
            answer["status"], answer["headers"] = message["status"], dict(message["headers"])

    await app(scope, receive, send)
    return answer["status"], {k.decode(): v.decode() for k, v in answer["headers"].items()}


def app_cpu(scheduler: str, root: Path, requests: int = 2000) -> dict:
    """:func:`_cpu_per_request` with the app called in this process through ASGI: the CPU
    of the routes, FastAPI and the job records without uvicorn and the kernel's sockets."""
    import asyncio

    from service.app import create_app
    from service.settings import Settings

    async def run() -> dict:
        app = create_app(Settings(scheduler=scheduler, results=root, max_open_cases=10**6))
        async with app.router.lifespan_context(app):
            return await _cpu_per_request(lambda *args: _asgi(app, *args), time.process_time, requests,
                                          40 * requests)

    return asyncio.run(run())


def percentiles(samples: list[float]) -> dict:
    ms = np.asarray(samples) * 1e3
    return {"n": int(ms.size), "p50_ms": float(np.percentile(ms, 50)), "p99_ms": float(np.percentile(ms, 99)),
            "max_ms": float(ms.max())}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.service", description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print the report as JSON")
    parser.add_argument("--clients", type=int, default=20)
    parser.add_argument("--submissions", type=int, default=200)
    parser.add_argument("--scheduler", default=None, help="use this scheduler instead of starting one")
    parser.add_argument("--workers", type=int, default=2, help="worker processes to start")
    parser.add_argument("--nice", type=int, default=0, help="CPU niceness of the started workers")
    parser.add_argument("--cpu", action="store_true",
                        help="only measure the API's CPU per request (one sequential client)")
    parser.add_argument("--max-open", type=int, default=400,
                        help="TUNNEL_CONTACT_MAX_OPEN_CASES of the service (the 429 threshold)")
    args = parser.parse_args(argv)

    with ExitStack() as stack:
        work = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="bench-service-")))
        scheduler = args.scheduler or stack.enter_context(running_cluster(args.workers, logs=work, nice=args.nice))
        url = stack.enter_context(running_service(work / "results", scheduler=scheduler,
                                                  log=work / "api.log", workers=1,
                                                  env={"TUNNEL_CONTACT_MAX_OPEN_CASES":
                                                       str(10**6 if args.cpu else args.max_open)}))
        if args.cpu:
            cpu = {"http": api_cpu(url), "in_process": app_cpu(scheduler, work / "in-process")}
            if args.json:
                print(json.dumps(cpu, indent=1))
                return 0
            for how, c in cpu.items():
                print(f"API CPU per request, {how.replace('_', ' ')} ({c['requests']} each, one client): "
                      f"POST /cases {c['post_cpu_ms']:.3f} ms, GET /cases/{{id}} {c['get_cpu_ms']:.3f} ms")
            return 0
        raw = load(url, args.clients, args.submissions)
        full = saturate(url, args.clients, offset=10 * args.submissions)

    report = {
        "clients": args.clients, "submissions": args.submissions, "wall_s": raw["wall"],
        "requests_per_s": (len(raw["posts"]) + len(raw["gets"])) / raw["wall"],
        "post_cases": percentiles(raw["posts"]), "get_case": percentiles(raw["gets"]),
        "errors": len(raw["errors"]), "error_samples": raw["errors"][:5],
        "queued_running_at_start": [raw["busy_before"]["queued"], raw["busy_before"]["running"]],
        "queued_running_at_end": [raw["busy_after"]["queued"], raw["busy_after"]["running"]],
        "max_open_cases": args.max_open,
        "bounded_queue": {"open_before": full["open_before"],
                          "accepted_before_first_429": full["accepted_before_first_429"],
                          "open_at_end": full["open_at_end"], "accepted_per_s": full["accepted_per_s"],
                          "post_429": percentiles(full["refused"]) if full["refused"] else None,
                          "errors": len(full["errors"]), "error_samples": full["errors"][:5]},
        "target_met": bool(raw["posts"] and raw["gets"] and not raw["errors"]
                           and percentiles(raw["posts"])["p99_ms"] < 50
                           and percentiles(raw["gets"])["p99_ms"] < 50),
    }
    if args.json:
        print(json.dumps(report, indent=1))
    else:
        print(f"{report['submissions']} submissions from {report['clients']} concurrent clients in "
              f"{report['wall_s']:.2f} s ({report['requests_per_s']:.0f} requests/s); workers busy: "
              f"queued/running {report['queued_running_at_start']} at start, "
              f"{report['queued_running_at_end']} at end")
        for name, key in (("POST /cases", "post_cases"), ("GET /cases/{id}", "get_case")):
            p = report[key]
            print(f"  {name:<16} n={p['n']:<4} p50 {p['p50_ms']:6.1f} ms  p99 {p['p99_ms']:6.1f} ms  "
                  f"max {p['max_ms']:6.1f} ms")
        print(f"  errors: {report['errors']}  target (p99 < 50 ms, no errors): "
              f"{'met' if report['target_met'] else 'NOT met'}")
        q = report["bounded_queue"]
        refused = q["post_429"] or {"n": 0, "p50_ms": float("nan"), "p99_ms": float("nan")}
        print(f"bounded queue (max {args.max_open} open cases): {q['open_before']} open, then "
              f"{q['accepted_before_first_429']} accepted at {q['accepted_per_s']:.0f}/s before the first 429; "
              f"{q['open_at_end']} open at the end; 429 answers n={refused['n']} p50 {refused['p50_ms']:.1f} ms "
              f"p99 {refused['p99_ms']:.1f} ms; other errors: {q['errors']}")
    return 0 if report["target_met"] else 1


if __name__ == "__main__":
    raise SystemExit(main())
