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


#: The mesh of the studies' cases: their statistics are the point, not mesh convergence (3× cheaper).
STUDY_MESH = {"interface_size": 0.5, "far_size": 16.0}


def sampled_sweep(name: str, samples: int, seed: int) -> dict:
    """A sampled sweep of a coarse case: K0 uniform, the load factor γF lognormal (SPEC §8)."""
    return {"name": name, "base": coarse_case(mesh=STUDY_MESH), "mode": "lhs", "samples": samples, "seed": seed,
            "vary": {"loads.lateral_ratio": {"distribution": "uniform", "low": 0.4, "high": 1.0},
                     "design.load_factor": {"distribution": "lognormal", "mean": 1.35, "std": 0.2}}}


#: The thinnest lining of a deep tunnel in C20 concrete that passes for K0 0.7 and 1.0 (SPEC §8).
THINNEST_SEARCH = {"name": "thinnest lining", "base": coarse_case(geometry={"depth": 40.0, "height": 80.0},
                                                                  design={"concrete_strength": 2.0e7}, mesh=STUDY_MESH),
                   "parameter": "geometry.thickness", "low": 0.15, "high": 0.5, "tolerance": 0.05,
                   "require": {"output": "max_utilization", "at_most": 1.0},
                   "over": {"loads.lateral_ratio": [0.7, 1.0]}}
