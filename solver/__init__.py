"""Tunnel lining / ground frictionless contact, Janovský & Procházka (1980) bolt-point method.

Pure numerics: ``CaseSpec -> run_case -> xarray.Dataset``. No files, no network.
"""
from .contact import NoAdmissibleBoltError, NotConvergedError, SolverError
from .run import run_case
from .spec import CaseSpec

__all__ = ["CaseSpec", "run_case", "SolverError", "NotConvergedError", "NoAdmissibleBoltError"]
