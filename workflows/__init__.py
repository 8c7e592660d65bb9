"""Stored computations: result files, combined results, sweeps on dask, studies, plots, commands.

Dependency direction: ``service -> workflows -> solver``. This package is the only
one that writes files; :class:`ResultStore` alone knows their layout. Every function
taking ``root`` accepts a store or the path of its folder. The studies of SPEC §8
(:func:`sensitivity`, :func:`reliability`, :func:`run_search`) are here as well.
"""
from __future__ import annotations

from .reliability_methods import reliability_study
from .result_store import ResultStore, open_case, open_results, run_and_store
from .studies import Search, reliability, run_search, sensitivity
from .sweep import MAX_SWEEP_CASES, Sweep, SweepError, expand_sweep, run_sweep

__all__ = ["MAX_SWEEP_CASES", "ResultStore", "Search", "Sweep", "SweepError", "expand_sweep", "open_case",
           "open_results", "reliability", "reliability_study", "run_and_store", "run_search", "run_sweep",
           "sensitivity"]
