"""Fixtures shared by the in-process service tests: a module's ``app`` fixture picks the
settings, ``client`` serves it (the lifespan runs: a real local dask cluster)."""
from __future__ import annotations

import pytest
from fastapi.testclient import TestClient


@pytest.fixture(scope="module")
def client(app):
    with TestClient(app) as c:
        yield c
