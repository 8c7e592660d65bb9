"""``run_case``: CaseSpec -> TunnelModel (mesh, assembly, factorization) -> solve -> Dataset."""
from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
import xarray as xr

from .results.dataset import to_dataset
from .results.mesh_check import add_mesh_check, mesh_changes, refined
from .limits import time_limit
from .model import TunnelModel
from .spec import CaseSpec
from .version import SOFTWARE_VERSION


def run_case(spec: CaseSpec, *, model: TunnelModel | None = None,
             time_limit_seconds: float | None = None, stop: Callable[[], bool] | None = None) -> xr.Dataset:
    """Solve one case (pure: no files, no network). Raises :class:`solver.SolverError`.

    ``model`` reuses a :class:`TunnelModel` built for a case with the same
    :func:`~solver.model.model_key` (mesh, stiffness and factorizations are then not rebuilt);
    the result is the same as without it. With ``solver.mesh_check`` the case is also solved on a
    mesh refined once (:mod:`solver.results.mesh_check`) and the changes are reported. The solve stops with a :class:`SolverError` past
    ``time_limit_seconds`` (default :func:`solver.limits.case_time_limit`), and with
    :class:`solver.limits.CaseCancelled` once ``stop()`` (asked twice a second) is true.
    """
    t0 = time.perf_counter()
    with time_limit(time_limit_seconds, stop):
        if model is None or not model.accepts(spec):
            model = TunnelModel(spec)
        ds = to_dataset(model, model.solve(spec), software_version=SOFTWARE_VERSION, started=t0)
        if spec.solver.mesh_check:
            fine_spec = refined(spec)
            fine_model = TunnelModel(fine_spec)
            fine = to_dataset(fine_model, fine_model.solve(fine_spec), software_version=SOFTWARE_VERSION)
            ds = add_mesh_check(ds, mesh_changes(ds, fine))
            ds["solve_seconds"].values = np.float64(time.perf_counter() - t0)
        return ds
