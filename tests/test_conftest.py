"""The suite's own plumbing (``tests/conftest.py``): what ``make test`` relies on to run in parallel."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

CONFTEST = Path(__file__).with_name("conftest.py")


def test_a_module_with_a_module_fixture_runs_on_one_process(tmp_path):
    """Under ``-n 2 --dist loadgroup`` a module whose tests share a module-scoped fixture keeps them on
    one process (its fixture built once), while tests without one are spread (pytest 9 reads the
    node id where xdist 3.8 no longer writes the group: the conftest writes it there)."""
    (tmp_path / "conftest.py").write_text(
        "import importlib.util\n"
        f"spec = importlib.util.spec_from_file_location('project_conftest', {str(CONFTEST)!r})\n"
        "project = importlib.util.module_from_spec(spec)\n"
        "spec.loader.exec_module(project)\n"
        "pytest_configure = project.pytest_configure\n"
        "pytest_collection_modifyitems = project.pytest_collection_modifyitems\n")
    body = ("import os, time\nimport pytest\n\n"
            "def record(kind):\n"
            "    with open({out!r}, 'a') as fh:\n"
            "        fh.write(kind + ' ' + os.environ.get('PYTEST_XDIST_WORKER', '-') + '\\n')\n\n")
    out = str(tmp_path / "workers.txt")
    (tmp_path / "test_shared.py").write_text(body.format(out=out) + (
        "@pytest.fixture(scope='module')\ndef shared():\n    return object()\n\n"
        "@pytest.mark.parametrize('i', range(8))\ndef test_shared(shared, i):\n"
        "    time.sleep(0.05)\n    record('shared')\n"))
    (tmp_path / "test_free.py").write_text(body.format(out=out) + (
        "@pytest.mark.parametrize('i', range(16))\ndef test_free(i):\n    time.sleep(0.1)\n    record('free')\n"))
    # only xdist's plugin loaded (the installed others, schemathesis's and hypothesis's, cost each of the
    # three processes seconds to import)
    run = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "xdist.plugin",
                          "-n", "2", "--dist", "loadgroup", str(tmp_path)], cwd=tmp_path, capture_output=True,
                         text=True, timeout=300, env={**os.environ, "PYTEST_DISABLE_PLUGIN_AUTOLOAD": "1"})
    assert run.returncode == 0, run.stdout + run.stderr
    lines = [line.split() for line in Path(out).read_text().splitlines()]
    shared = {w for kind, w in lines if kind == "shared"}
    free = {w for kind, w in lines if kind == "free"}
    assert len([1 for kind, _ in lines if kind == "shared"]) == 8 and len(shared) == 1, lines
    assert free == {"gw0", "gw1"}, lines  # the others are spread over both


def test_the_serial_part_finds_every_serial_test_by_its_file():
    """``make test``'s serial part imports only the files that define a :data:`SERIAL_TESTS` name
    (``pytest_ignore_collect``): each name must still be defined, in one file, as ``def name(``."""
    import runpy

    SERIAL_TESTS = runpy.run_path(str(CONFTEST))["SERIAL_TESTS"]  # (another conftest module is named so too)

    files = [p for p in Path(__file__).parent.rglob("test_*.py")]
    homes = {name: [p for p in files if f"def {name}(" in p.read_text(encoding="utf-8")] for name in SERIAL_TESTS}
    assert {name: len(found) for name, found in homes.items()} == dict.fromkeys(SERIAL_TESTS, 1)
