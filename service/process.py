"""Running the service as child processes on loopback: for the demo, the benchmark and tests.

Each child gets its own process group, so stopping it also stops what it spawned
(a dask worker's nanny and worker, an embedded cluster's worker processes).
"""
from __future__ import annotations

import logging
import os
import random
import signal
import socket
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Iterator, Optional, Sequence

import httpx

from workflows.workers import cluster_process_env, worker_process_env

logger = logging.getLogger(__name__)


#: Where :func:`free_port` looks: below the kernel's ephemeral range (see :func:`ephemeral_ports`).
FIXED_PORTS = range(20000, 32768)


def ephemeral_ports() -> range:
    """The ports the kernel hands out for port 0 and outgoing connections: read on Linux, else Linux's
    default 32768-60999 (other systems use 49152-65535: :data:`FIXED_PORTS` lies below both)."""
    try:
        low, high = map(int, Path("/proc/sys/net/ipv4/ip_local_port_range").read_text().split()[:2])
        return range(low, high + 1)
    except (OSError, ValueError):
        return range(32768, 61000)


def free_port(ports: range = FIXED_PORTS) -> int:
    """A TCP port on 127.0.0.1 that nothing listens on right now, chosen outside the ephemeral range.

    A port the kernel picked for port 0 is free when this returns, but another process binding
    port 0 (a dask worker's HTTP pages, a client's outgoing connection) may get it before the
    caller's server binds it. Ports drawn at random below the ephemeral range are never handed
    out that way; if that range is empty here, fall back to the kernel's pick.
    """
    ephemeral = ephemeral_ports()
    candidates = [p for p in ports if p not in ephemeral]
    # from the system's randomness: forked processes share the random module's state
    for port in random.SystemRandom().sample(candidates, min(64, len(candidates))):
        with socket.socket() as s:
            try:
                s.bind(("127.0.0.1", port))
            except OSError:
                continue
            return port
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start(args: Sequence[str], *, log: Optional[Path] = None, env: Optional[dict] = None) -> subprocess.Popen:
    """Start ``args`` in a new process group, output to ``log`` (or discarded)."""
    out: IO | int = open(log, "ab") if log is not None else subprocess.DEVNULL
    try:
        return subprocess.Popen(list(args), stdout=out, stderr=subprocess.STDOUT, start_new_session=True,
                                env={**os.environ, **(env or {})})
    finally:
        if log is not None:
            out.close()


def stop(process: subprocess.Popen, *, timeout: float = 10.0, sig: int = signal.SIGTERM) -> None:
    """Signal ``process``'s group (SIGTERM by default), then SIGKILL it if it lingers."""
    if process.poll() is None:
        try:
            os.killpg(process.pid, sig)
        except ProcessLookupError:
            pass
    try:
        process.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        pass
    try:  # children of a killed leader may survive it
        os.killpg(process.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    process.wait(timeout=timeout)


def api_command(*, port: int, results: Path | str, scheduler: Optional[str] = None) -> list[str]:
    """Command line of ``tunnel-contact -v serve`` on 127.0.0.1:``port`` with this interpreter."""
    args = [sys.executable, "-m", "service.cli", "-v", "serve", "--host", "127.0.0.1", "--port", str(port),
            "--results", str(results)]
    return args + (["--scheduler", scheduler] if scheduler else [])


def wait_healthy(url: str, *, timeout: float = 60.0, workers: int = 1,
                 process: Optional[subprocess.Popen] = None) -> dict:
    """Poll ``url``/health until it answers 200 with at least ``workers`` workers; return the body.

    Raises
    ------
    RuntimeError
        If ``process`` exits first, or ``timeout`` s pass.
    """
    deadline = time.monotonic() + timeout
    last = "no answer"
    while time.monotonic() < deadline:
        if process is not None and process.poll() is not None:
            raise RuntimeError(f"service exited with code {process.returncode} before it was healthy")
        try:
            response = httpx.get(f"{url}/health", timeout=2.0)
            last = f"{response.status_code} {response.text[:200]}"
            body = response.json() if response.status_code == 200 else {}
            if isinstance(body, dict) and body.get("workers", -1) >= workers:
                return body
        except ValueError:  # not our service's JSON: something else holds the port
            pass
        except httpx.HTTPError as exc:
            last = str(exc)
        time.sleep(0.2)
    raise RuntimeError(f"{url} not healthy after {timeout} s: {last}")


def dask_command(*args: str) -> list[str]:
    """Command line of the ``dask`` CLI installed next to this interpreter."""
    return [str(Path(sys.executable).with_name("dask")), *args]


#: Where dask's HTTP pages listen in this topology: loopback, a free port.
LOOPBACK_ANY_PORT = "127.0.0.1:0"


def worker_command(address: str, name: str) -> list[str]:
    """Command line of one single-threaded ``dask worker`` on loopback for ``address``."""
    return dask_command("worker", address, "--nthreads", "1", "--host", "127.0.0.1", "--no-dashboard",
                        "--dashboard-address", LOOPBACK_ANY_PORT, "--name", name)


@contextmanager
def running_cluster(n_workers: int = 2, *, logs: Optional[Path] = None, nice: int = 0,
                    port: Optional[int] = None, env: Optional[dict] = None) -> Iterator[str]:
    """A ``dask scheduler`` and ``n_workers`` single-threaded ``dask worker`` processes on
    loopback (the deployment's topology); yield the scheduler address, stop them on exit.

    ``nice`` > 0 lowers the workers' CPU priority (so the API stays responsive when
    they share its cores); ``port`` is the scheduler's (default: a free one); ``env``
    is added to every process's environment (e.g. ``DASK_DISTRIBUTED__...`` settings).
    Every port listens on loopback only: with ``--no-dashboard`` dask still serves its
    HTTP pages (health, metrics), by default on all interfaces and port 8787.
    """
    port = port or free_port()
    address = f"tcp://127.0.0.1:{port}"
    log = (lambda name: logs / f"{name}.log") if logs is not None else (lambda name: None)
    processes = []
    try:
        processes.append(start(dask_command("scheduler", "--host", "127.0.0.1", "--port", str(port),
                                             "--no-dashboard", "--dashboard-address", LOOPBACK_ANY_PORT),
                               log=log("scheduler"), env={**cluster_process_env(), **(env or {})}))
        for i in range(n_workers):
            niced = ["nice", "-n", str(nice)] if nice else []
            processes.append(start(niced + worker_command(address, f"worker-{i}"), log=log(f"worker-{i}"),
                                   env={**worker_process_env(), **(env or {})}))
        yield address
    finally:
        for process in reversed(processes):
            stop(process)


@contextmanager
def running_service(results: Path | str, *, scheduler: Optional[str] = None, log: Optional[Path] = None,
                    timeout: float = 90.0, env: Optional[dict] = None, workers: int = 1) -> Iterator[str]:
    """Run the service (embedded cluster unless ``scheduler``) on a free port; yield its URL.

    The service is stopped on exit, also on an exception or Ctrl-C.
    """
    port = free_port()
    url = f"http://127.0.0.1:{port}"
    process = start(api_command(port=port, results=results, scheduler=scheduler), log=log, env=env)
    logger.info("service starting at %s (pid %d)", url, process.pid)
    try:
        wait_healthy(url, timeout=timeout, process=process, workers=workers)
        yield url
    finally:
        stop(process)
        logger.info("service at %s stopped", url)
