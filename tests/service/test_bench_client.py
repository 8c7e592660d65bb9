"""The benchmark's light HTTP client reads what httpx reads, from a real uvicorn server.

``bench.service`` writes its requests by hand and parses the answers with httptools (its
own CPU would otherwise show as the service's latency); these tests hold it to a
standard client on the answers the service gives: 202 with a Location, 404, 429 with
Retry-After, a body larger than one socket read, many requests on one connection.
"""
from __future__ import annotations

import threading
import time

import httpx
import pytest
import uvicorn
from fastapi import FastAPI, Request, Response
from fastapi.responses import JSONResponse

from bench.service import CLIENT_ERRORS, LightClient
from service.process import free_port

BIG = "x" * 300_000  # several socket reads


def _app() -> FastAPI:
    app = FastAPI()

    @app.post("/cases")
    async def post(request: Request) -> Response:
        body = await request.json()
        return JSONResponse({"echo": body}, status_code=202, headers={"Location": f"/cases/{body['i']}"})

    @app.get("/cases/{i}")
    async def get(i: int) -> Response:
        if i == 404:
            return JSONResponse({"detail": "unknown case 404"}, status_code=404)
        if i == 429:
            return JSONResponse({"detail": "full"}, status_code=429, headers={"Retry-After": "30"})
        return JSONResponse({"i": i, "big": BIG if i == 7 else ""})

    @app.get("/close")
    async def close() -> Response:
        return Response("bye", headers={"Connection": "close"})

    return app


@pytest.fixture(scope="module")
def url():
    port = free_port()
    server = uvicorn.Server(uvicorn.Config(_app(), host="127.0.0.1", port=port, log_level="warning"))
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    deadline = time.monotonic() + 30
    while not server.started:
        assert time.monotonic() < deadline and thread.is_alive(), "server did not start"
        time.sleep(0.01)
    yield f"http://127.0.0.1:{port}"
    server.should_exit = True
    thread.join(10)


@pytest.mark.parametrize("method, path, body", [
    ("POST", "/cases", {"i": 3, "spec": {"geometry": {"depth": 20.0}}}),
    ("GET", "/cases/5", None), ("GET", "/cases/7", None), ("GET", "/cases/404", None), ("GET", "/cases/429", None),
])
def test_light_client_reads_what_httpx_reads(url, method, path, body):
    client = LightClient(url)
    try:
        status, headers, content = client.request(method, path, body)
    finally:
        client.close()
    reference = httpx.request(method, url + path, json=body)
    assert status == reference.status_code
    assert content == reference.content
    assert headers == {k.lower(): v for k, v in reference.headers.items() if k.lower() != "date"} | {
        "date": headers["date"]}


def test_one_connection_carries_many_requests_and_a_close_is_an_error(url):
    client = LightClient(url)
    try:
        for i in range(50):
            status, headers, content = client.request("POST", "/cases", {"i": i})
            assert status == 202 and headers["location"] == f"/cases/{i}"
            assert client.request("GET", headers["location"])[0] == 200
        assert client.request("GET", "/close")[2] == b"bye"
        with pytest.raises(CLIENT_ERRORS):
            client.request("GET", "/cases/1")  # the server has closed the connection
    finally:
        client.close()
