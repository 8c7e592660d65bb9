"""A real PostgreSQL on loopback for the tests of the multi-machine deployment: a cluster made by
``initdb`` in a temporary folder (Debian's ``postgresql`` package; the Makefile installs it). The
S3-compatible server (moto's server mode) is the ``s3`` fixture of ``tests/conftest.py``."""
from __future__ import annotations

import os
import pwd
import shutil
import subprocess
import tempfile
import uuid
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

import pytest

from service.process import free_port

#: Where Debian's ``postgresql`` package puts its programs (not on PATH), newest version first.
POSTGRES_BINS = sorted(Path("/usr/lib/postgresql").glob("*/bin"), key=lambda p: int(p.parent.name), reverse=True) \
    if Path("/usr/lib/postgresql").is_dir() else []


def _pg_tool(name: str) -> str:
    found = shutil.which(name) or next((str(b / name) for b in POSTGRES_BINS if (b / name).exists()), None)
    if found is None:
        pytest.skip(f"PostgreSQL's {name} is not installed (make sysdeps installs Debian's postgresql)")
    return found


def _as_server_user(args: list[str]) -> list[str]:
    """``initdb`` and the server refuse to run as root: as root they run as ``nobody``."""
    if os.geteuid() != 0:
        return args
    return ["runuser", "-u", pwd.getpwuid(65534).pw_name, "--", *args]


@contextmanager
def server_folder() -> Iterator[Path]:
    """A new temporary folder the server's user can enter (pytest's ``tmp_path`` is root's
    alone when the tests run as root), removed afterwards."""
    folder = Path(tempfile.mkdtemp(prefix="tunnel-contact-pg-"))
    try:
        yield folder
    finally:
        shutil.rmtree(folder, ignore_errors=True)


@contextmanager
def postgres_server(folder: Path) -> Iterator[str]:
    """A PostgreSQL server on a free loopback port with its data and unix socket in ``folder``;
    yields the URL of its ``postgres`` database (user ``postgres``, trust on loopback)."""
    folder.mkdir(parents=True, exist_ok=True)
    if os.geteuid() == 0:
        os.chown(folder, 65534, 65534)
    data, port = folder / "data", free_port()
    _run(_as_server_user([_pg_tool("initdb"), "-D", str(data), "-A", "trust", "-U", "postgres", "--no-sync",
                          "-E", "UTF8"]))
    pg_ctl = _pg_tool("pg_ctl")
    _run(_as_server_user([pg_ctl, "-D", str(data), "-l", str(folder / "server.log"), "-w", "-o",
                          f"-h 127.0.0.1 -p {port} -k {folder} -F -c max_connections=200", "start"]))
    try:
        yield f"postgresql://postgres@127.0.0.1:{port}/postgres"
    finally:
        subprocess.run(_as_server_user([pg_ctl, "-D", str(data), "-m", "immediate", "-w", "stop"]),
                       capture_output=True)


def _run(args: list[str]) -> None:
    done = subprocess.run(args, capture_output=True, text=True)
    if done.returncode:
        raise RuntimeError(f"{' '.join(args)} failed ({done.returncode}): {done.stdout} {done.stderr}")


def new_database(server_url: str) -> str:
    """A new empty database on the server of ``server_url``; its URL."""
    import sqlalchemy as sa

    name = f"t_{uuid.uuid4().hex[:12]}"
    engine = sa.create_engine(server_url.replace("postgresql://", "postgresql+psycopg://"),
                              isolation_level="AUTOCOMMIT")
    with engine.connect() as db:
        db.exec_driver_sql(f"CREATE DATABASE {name}")
    engine.dispose()
    return server_url.rsplit("/", 1)[0] + f"/{name}"
