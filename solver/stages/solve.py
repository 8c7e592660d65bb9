"""One case on a built model, stage after stage (SPEC §1.1):

1. the in-situ state σ0 (no solve: zero displacement; its excavation load is the discrete
   one, :mod:`.loads`);
2. the excavation: stage 1 releases λd of it on the ground alone;
3. the lining placed, with its weight and the water, and the rest released with contact
   (:mod:`.contact`), recovered and checked (:mod:`.recovery`).

Yielding ground follows the same stages incrementally (:func:`.plastic.solve_staged`).
"""
from __future__ import annotations

import time
from ..build import BuiltModel
from ..errors import SolverError
from ..fe.flexibility import rows_of_model
from ..fe.linalg import blas_threads
from ..spec import CaseSpec
from .contact import forward_stage
from .face import install, with_deconfinement
from .plastic import solve_staged
from .recovery import finish
from .state import KKT_ACCEPT, Solution, accepted_residual


def solve_case(model: BuiltModel, spec: CaseSpec) -> Solution:
    """Solve ``spec`` on ``model`` (which must share its :func:`~solver.model.model_key`)."""
    if not model.accepts(spec):
        raise ValueError("the case does not share this model's geometry, mesh, boundaries and materials")
    t0 = time.perf_counter()
    model = model.for_case(spec)
    with blas_threads():
        rows = rows_of_model(spec.interface.model)
        model.factorize(rows)
        installed = None
        if spec.excavation.face_distance is not None:  # λd found, not given (SPEC §9.5)
            installed = install(model, spec, rows)
            spec = with_deconfinement(spec, installed.deconfinement)
        if spec.plastic:
            sol = solve_staged(model, spec, rows, t0)
        else:
            loads, stage, d, F2 = forward_stage(model, spec, rows)
            sol = finish(model, spec, rows, loads, stage, d, F2, t0)
        sol.installation = installed
    limit = accepted_residual(spec.solver.tolerance)
    if not sol.kkt_residual <= limit:  # NaN too: never a result above the tolerance
        raise SolverError(
            f"solver: the discrete KKT residual of the answer is {sol.kkt_residual:.3g}, above the accepted "
            f"{limit:.3g} (max of solver.tolerance and {KKT_ACCEPT:g}); the inputs are probably at the edge of "
            "what double precision resolves (e.g. loads or stiffnesses many orders of magnitude apart)")
    return sol
