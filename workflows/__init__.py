"""Stored computations: result files, combined results, sweeps on dask, studies, plots, commands.

Dependency direction: ``service -> workflows -> solver``. This package is the only
one that writes files; :class:`ResultStore` alone knows their layout. Every function
taking ``root`` accepts a store or the path of its folder. The studies of SPEC §8
(:func:`sensitivity`, :func:`reliability`, :func:`run_search`) are here as well.
"""
from __future__ import annotations

from solver.lazy import lazy_exports

#: Where each name of the package lives: imported on first use (PEP 562), so that a process
#: needing one module (a worker's case, the CLI's ``show``) does not import every study's
#: libraries (scikit-learn, SALib, scipy.stats) at start.
_HOME = {
    "reliability_study": ".reliability_methods",
    "ResultStore": ".result_store", "open_case": ".result_store", "open_results": ".result_store",
    "run_and_store": ".result_store",
    "Search": ".studies", "reliability": ".studies", "run_search": ".studies", "sensitivity": ".studies",
    "MAX_SWEEP_CASES": ".sweep", "Sweep": ".sweep", "SweepError": ".sweep", "expand_sweep": ".sweep",
    "run_sweep": ".sweep",
}

__all__ = sorted(_HOME)
__getattr__, __dir__ = lazy_exports(__name__, _HOME)
