"""Studies over REST (SPEC §8): a sampled sweep's sensitivity and reliability (JSON and
figures), bad outputs named, and a search that survives a restart of the API and its workers
(the lifespan of one app ends, a new app on the same store resumes it)."""
from __future__ import annotations

import time

import pytest
from fastapi.testclient import TestClient

from service.app import create_app
from service.settings import Settings
from service_helpers import THINNEST_SEARCH, sampled_sweep

SAMPLED = sampled_sweep("lhs", 128, 5)
SEARCH = THINNEST_SEARCH


def _app(root):
    return create_app(Settings(results=root, local_workers=2, poll_interval=0.1, reconcile_interval=3600))


def _until(fn, timeout=240.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = fn()
        if value:
            return value
        time.sleep(0.2)
    raise AssertionError("timed out")


@pytest.mark.slow
def test_analyses_and_a_search_across_a_restart(tmp_path):
    with TestClient(_app(tmp_path)) as client:
        sweep = client.post("/sweeps", json=SAMPLED).json()
        sid = sweep["id"]
        assert client.get(f"/sweeps/{sid}/sensitivity", params={"output": "max_abs_moment"}).status_code in (200, 409)
        _until(lambda: client.get(f"/sweeps/{sid}").json()["counts"]["done"] == 128)
        s = client.get(f"/sweeps/{sid}/sensitivity", params={"output": "max_abs_moment"}).json()
        assert s["method"].startswith("delta") and s["samples"] == 128
        by = {p["parameter"]: p for p in s["parameters"]}
        assert set(by) == {"loads.lateral_ratio", "design.load_factor"}
        assert by["loads.lateral_ratio"]["first_order"] > 0.5
        gamma = by["design.load_factor"]  # the moment does not depend on the load factor:
        assert 0 < s["noise_floor"] < 0.3  # its interval reaches the floor: not told from zero
        assert gamma["first_order"] - gamma["first_order_ci"] <= s["noise_floor"]
        assert by["loads.lateral_ratio"]["first_order"] - by["loads.lateral_ratio"]["first_order_ci"] > s["noise_floor"]
        assert by["loads.lateral_ratio"]["total_order"] is None  # the delta method gives none
        bad = client.get(f"/sweeps/{sid}/sensitivity", params={"output": "moment"})
        assert bad.status_code == 422 and bad.json()["errors"][0]["field"] == "output"
        r = client.get(f"/sweeps/{sid}/reliability", params={"limit": 0.5}).json()
        assert r["samples"] == 128 and r["ci_low"] <= r["probability"] <= r["ci_high"]
        for path in ("sensitivity.png?output=max_abs_moment", "reliability.png"):
            png = client.get(f"/sweeps/{sid}/{path}")
            assert png.status_code == 200 and png.content[:4] == b"\x89PNG", path
        (tmp_path / "sensitivity.png").write_bytes(client.get(f"/sweeps/{sid}/sensitivity.png",
                                                              params={"output": "max_abs_moment"}).content)
        (tmp_path / "reliability.png").write_bytes(client.get(f"/sweeps/{sid}/reliability.png",
                                                              params={"limit": 0.5}).content)
        page = client.get(f"/ui/sweeps/{sid}", params={"output": "max_thrust", "limit": 0.5}).text
        assert 'data-plot="sensitivity"' in page and "sensitivity.png?output=max_thrust" in page
        assert "reliability.png?output=max_utilization&amp;limit=0.5" in page
        # a search: stop the API (and its workers) once the first trial is recorded
        posted = client.post("/searches", json=SEARCH)
        assert posted.status_code == 202
        ident = posted.json()["id"]
        assert client.post("/searches", json={**SEARCH, "low": 0.6}).status_code == 422
        _until(lambda: len(client.get(f"/searches/{ident}").json()["trials"]) >= 1)
    with TestClient(_app(tmp_path)) as client:  # a new API, new workers, the same store
        done = _until(lambda: (lambda r: r if r["status"] != "running" else None)(
            client.get(f"/searches/{ident}").json()))
        assert done["status"] == "done" and done["satisfied"], done
        values = [t["value"] for t in done["trials"]]
        assert values[:2] == [0.5, 0.15] and len(values) <= done["max_trials"] == 5
        answer = next(t for t in done["trials"] if t["value"] == done["value"])
        assert answer["satisfied"] and answer["worst"] <= 1.0
        assert not any(t["satisfied"] for t in done["trials"] if t["value"] < done["value"])
        ids = [c for t in done["trials"] for c in t["case_ids"]]
        assert len(set(ids)) == 2 * len(values)
        assert all(client.get(f"/cases/{c}").json()["status"] == "done" for c in ids)
        assert [s["id"] for s in client.get("/searches").json()["items"]] == [ident]
        page = client.get(f"/ui/searches/{ident}").text
        assert f"geometry.thickness = {done['value']:.4g}" in page and page.count("<tr><td class=\"num\">") == len(values)
        assert f'href="/ui/searches/{ident}"' in client.get("/").text
        png = client.get(f"/searches/{ident}/trials.png")
        assert png.status_code == 200 and png.content[:4] == b"\x89PNG"
        (tmp_path / "trials.png").write_bytes(png.content)
        assert client.get("/searches/0123456789abcdef").status_code == 404
