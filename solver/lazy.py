"""A package's names imported on first use (PEP 562): ``__getattr__`` and ``__dir__`` for its
``__init__``, so that a process needing one module does not import the rest at start (``solver``:
the command line's parser needs no finite elements; ``workflows``: a worker's case or the command
line's ``show`` needs no study's libraries, scikit-learn, SALib, scipy.stats)."""
from __future__ import annotations

import importlib


def lazy_exports(package: str, home: dict[str, str]):
    """``(__getattr__, __dir__)`` of ``package`` whose name ``n`` lives in its module ``home[n]``
    (relative, e.g. ``".sweep"``)."""
    namespace = importlib.import_module(package).__dict__

    def __getattr__(name: str):
        if name in home:
            value = getattr(importlib.import_module(home[name], package), name)
            namespace[name] = value
            return value
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def __dir__() -> list[str]:
        return sorted(set(namespace) | set(home))

    return __getattr__, __dir__
