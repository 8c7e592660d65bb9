"""Tunnel lining / ground contact, Janovský & Procházka (1980) bolt-point method.

Isoparametric P2 plane-strain elasticity, construction stages (in-situ stress, deconfinement),
frictionless, Coulomb or bonded interfaces, EN 1992-1-1 section check. Pure numerics:
``CaseSpec -> TunnelModel -> solve -> to_dataset -> xarray.Dataset`` (``run_case``). No files,
no network.
"""
from .errors import NoAdmissibleBoltError, NotConvergedError, SolverError
from .lazy import lazy_exports
from .spec import CaseSpec

__all__ = ["CaseSpec", "run_case", "SolverError", "NotConvergedError", "NoAdmissibleBoltError"]


#: ``run_case`` imported on first use (PEP 562): a process that only reads or validates cases (the
#: command line's ``--help``, ``--version``, a bad argument) does not import the finite elements.
__getattr__, __dir__ = lazy_exports(__name__, {"run_case": ".run"})
