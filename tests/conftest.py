"""The suite runs on two processes (``make test``: pytest-xdist, ``--dist loadgroup``); this
file decides what may not be spread.

- A test module with a module-scoped fixture (a served app with its dask cluster, a browser,
  a solved study) keeps its tests on one process: ``xdist_group`` named after the module, so
  the fixture is built once, not once per process.
- A test that compares times measured while it runs (a speed ratio, a pause, the spread of
  eight solves) is ``serial``: ``make test`` runs those after the parallel part, alone on the
  machine, so the other process's load cannot skew the ratio they check.
"""
from __future__ import annotations

import pytest

#: Tests whose assertion compares times they measure (matched by function name: the solver's
#: tests move with their modules).
SERIAL_TESTS = frozenset({
    "test_eight_default_cases_in_a_loaded_plain_process_have_no_outlier",
    "test_factorization_releases_the_gil",
    "test_rejects_unknown_options_and_is_fast",
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


@pytest.hookimpl(tryfirst=True)  # before xdist reads the groups
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        if getattr(item, "originalname", item.name) in SERIAL_TESTS:
            item.add_marker(pytest.mark.serial)
        if _module_scoped(item) and not item.get_closest_marker("xdist_group"):
            item.add_marker(pytest.mark.xdist_group(item.nodeid.split("::")[0]))
