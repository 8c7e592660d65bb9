"""The helpers that run the service as child processes: ports no other process can take
from under them, and a health wait that is not fooled by another server on the port."""
from __future__ import annotations

import socket
import subprocess
import sys
import threading
from http.server import BaseHTTPRequestHandler, HTTPServer

import pytest

from service.process import ephemeral_ports, free_port, wait_healthy


def test_free_ports_are_outside_the_range_the_kernel_hands_out_for_port_zero():
    """A port the kernel picks for port 0 (a dask worker's pages, an outgoing connection) may
    be taken by another process before our server binds it; ours come from below that range."""
    ephemeral = ephemeral_ports()
    ports = {free_port() for _ in range(20)}
    assert not any(p in ephemeral for p in ports)
    assert len(ports) > 1  # drawn at random: two test processes do not walk the same list
    for port in ports:
        with socket.socket() as s:
            s.bind(("127.0.0.1", port))


class _PlainOk(BaseHTTPRequestHandler):
    """What a dask server answers on /health: 200 and the text ``ok``."""

    def do_GET(self):  # noqa: N802 (http.server's name)
        self.send_response(200)
        self.end_headers()
        self.wfile.write(b"ok")

    def log_message(self, *args):
        pass


@pytest.fixture
def foreign_server():
    server = HTTPServer(("127.0.0.1", 0), _PlainOk)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{server.server_address[1]}"
    server.shutdown()
    server.server_close()


def test_a_foreign_server_on_the_port_is_not_taken_for_the_service(foreign_server):
    """Another program answering 200 "ok" on the port: the wait says our process exited
    (it could not bind), not a JSON decoding error, and never returns that answer."""
    process = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(0.5)"])
    try:
        with pytest.raises(RuntimeError, match="exited with code 0"):
            wait_healthy(foreign_server, timeout=30, process=process)
    finally:
        process.wait()
    with pytest.raises(RuntimeError, match="not healthy after 1 s: 200 ok"):
        wait_healthy(foreign_server, timeout=1)
