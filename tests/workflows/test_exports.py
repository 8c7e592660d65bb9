"""The packages' exports (SPEC §8 names them on ``workflows``): each name is what its module
defines, whatever was imported before (a submodule of the same name must not shadow it), and
importing the package imports no study's libraries."""
from __future__ import annotations

import importlib
import pkgutil
import subprocess
import sys
import types

import pytest


@pytest.mark.parametrize("package", ["workflows", "workflows.reliability_methods"])
def test_every_exported_name_is_its_definition_after_every_submodule_is_imported(package):
    pkg = importlib.import_module(package)
    for info in pkgutil.iter_modules(pkg.__path__):
        importlib.import_module(f"{package}.{info.name}")
    for name in pkg.__all__:
        value = getattr(pkg, name)
        assert not isinstance(value, types.ModuleType), f"{package}.{name} is a module"
        assert getattr(value, "__module__", package).startswith(package), name
    assert set(pkg.__all__) <= set(dir(pkg))
    with pytest.raises(AttributeError, match="no attribute"):
        getattr(pkg, "no_such_name")


def test_importing_workflows_imports_no_study_library():
    code = ("import sys, workflows; from workflows import ResultStore; "
            "print(sorted(m for m in ('sklearn', 'SALib', 'openturns') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
