"""Helpers of the service tests: coarse cases that solve in well under a second, polling."""
from __future__ import annotations

import time

import pytest

#: Mesh settings that make a case solve in a fraction of a second.
COARSE = {"mesh": {"interface_size": 0.25, "far_size": 8.0}}


def coarse_case(**sections) -> dict:
    """A coarse case JSON with some sections overridden (``ground={"young": 2e7}``)."""
    case = {key: dict(value) for key, value in COARSE.items()}
    for section, fields in sections.items():
        case.setdefault(section, {}).update(fields)
    return case


def wait_until(condition, *, timeout: float = 60.0, interval: float = 0.1, what: str = "condition"):
    """Poll ``condition()`` until it returns something truthy; return that."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = condition()
        if value:
            return value
        time.sleep(interval)
    pytest.fail(f"timed out after {timeout} s waiting for {what}")


def finished(client, case_id: str) -> dict:
    """The record of ``case_id`` once it is done or failed (``client``: an HTTP test client)."""
    def check():
        body = client.get(f"/cases/{case_id}").json()
        return body if body["status"] in ("done", "failed") else None
    return wait_until(check, what=f"case {case_id}")
