"""The dask task: one case in, a small summary out (no field arrays cross the wire)."""
from __future__ import annotations

import logging
import time

from solver.spec import CaseSpec

from .store import is_stored, run_and_store
from .summary import read_summary

logger = logging.getLogger(__name__)


def solve_and_store(spec_json: str, root: str, force: bool = False) -> dict:
    """Solve the case ``spec_json`` into the store at ``root`` unless it is stored.

    A pure function of its arguments (the same case always gives the same file), so
    it is safe to run on any worker that sees ``root``.

    Parameters
    ----------
    spec_json : the case as JSON (validated here again).
    root : folder of the result store, as seen by the worker.
    force : recompute even if the result exists.

    Returns
    -------
    dict
        ``{"case_id", "status": "done" | "failed", "error": str | None,
        "summary": {scalar name: float}, "computed": bool, "seconds": float}``;
        ``summary`` is empty for a failed case. Solver failures are returned (and
        recorded in the store), not raised.

    Raises
    ------
    pydantic.ValidationError
        If ``spec_json`` is not a valid case.
    """
    spec = CaseSpec.model_validate_json(spec_json)
    case_id = spec.case_id
    computed = force or not is_stored(root, case_id)
    start = time.perf_counter()
    try:
        run_and_store(spec, root, force=force)
    except Exception as exc:  # recorded in the store by run_and_store; the sweep goes on
        return {"case_id": case_id, "status": "failed", "error": f"{type(exc).__name__}: {exc}",
                "summary": {}, "computed": True, "seconds": time.perf_counter() - start}
    return {"case_id": case_id, "status": "done", "error": None,
            "summary": read_summary(root, case_id), "computed": computed,
            "seconds": time.perf_counter() - start}
