"""Stored computations: result files, combined results, sweeps on dask, plots, commands.

Dependency direction: ``service -> workflows -> solver``. This package is the only
one that writes files; :class:`ResultStore` alone knows their layout. Every function
taking ``root`` accepts a store or the path of its folder.
"""
from __future__ import annotations

from .combine import open_results
from .reliability import reliability_study
from .result_store import ResultStore, open_case, run_and_store
from .sweep import MAX_SWEEP_CASES, Sweep, SweepError, expand_sweep, run_sweep

__all__ = ["MAX_SWEEP_CASES", "ResultStore", "Sweep", "SweepError", "expand_sweep", "open_case",
           "open_results", "reliability_study", "run_and_store", "run_sweep"]
