"""Tunnel lining / ground contact, Janovský & Procházka (1980) bolt-point method.

Isoparametric P2 plane-strain elasticity, construction stages (in-situ stress, deconfinement),
frictionless, Coulomb or bonded interfaces, EN 1992-1-1 section check. Pure numerics:
``CaseSpec -> TunnelModel -> solve -> to_dataset -> xarray.Dataset`` (``run_case``). No files,
no network.
"""
from .errors import NoAdmissibleBoltError, NotConvergedError, SolverError
from .run import run_case
from .spec import CaseSpec

__all__ = ["CaseSpec", "run_case", "SolverError", "NotConvergedError", "NoAdmissibleBoltError"]
