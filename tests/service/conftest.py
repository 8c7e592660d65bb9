"""Fixtures shared by the in-process service tests: a module's ``app`` fixture picks the
settings, ``client`` serves it (the lifespan runs: a real local dask cluster)."""
from __future__ import annotations

import pytest
from fastapi.testclient import TestClient


@pytest.fixture(scope="module")
def client(app):
    with TestClient(app) as c:
        yield c


@pytest.fixture(scope="session")
def postgres():
    """A PostgreSQL server for the session (see :mod:`real_servers`); its URL."""
    from real_servers import postgres_server, server_folder

    with server_folder() as folder, postgres_server(folder) as url:
        yield url


@pytest.fixture
def database_url(postgres):
    """A new empty PostgreSQL database for one test; its URL."""
    from real_servers import new_database

    return new_database(postgres)
