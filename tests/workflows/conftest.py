"""Fixtures of the workflow tests."""
from __future__ import annotations

import pytest


@pytest.fixture(scope="module")
def client():
    """A real two-worker LocalCluster for the module, set up as the command line sets up its own
    (:func:`workflows.sweep.local_client`: worker processes forked from one preloaded server)."""
    from workflows.sweep import local_client

    with local_client(2) as c:
        yield c
