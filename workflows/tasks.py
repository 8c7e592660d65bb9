"""The dask task: one case in, a small summary out (no field arrays cross the wire).

:func:`task_key` names the task of a case for every submitter (the command line's
sweeps and the service), so on a shared scheduler a case submitted twice runs once.
"""
from __future__ import annotations

import logging
import time
from collections.abc import Sequence

from solver.limits import CaseCancelled
from solver.spec import CaseSpec

from .result_store import StoreLike, as_store
from .workers import release_memory

logger = logging.getLogger(__name__)

#: Prefix of the dask key of a case's task; the rest is the case id.
TASK_KEY_PREFIX = "solve_and_store-"


def task_key(case_id: str) -> str:
    """Dask key of the task computing ``case_id`` (stable across processes and restarts)."""
    return f"{TASK_KEY_PREFIX}{case_id}"


def case_id_of_key(key: object) -> str | None:
    """The case id in a :func:`task_key`, or None for any other key."""
    if isinstance(key, str) and key.startswith(TASK_KEY_PREFIX):
        return key[len(TASK_KEY_PREFIX):]
    return None


def solve_and_store(spec_json: str, root: StoreLike, force: bool = False) -> dict:
    """Solve the case ``spec_json`` into the store at ``root`` unless it is stored and
    readable (:meth:`ResultStore.solve_or_read`: a truncated file is computed again).

    A pure function of its arguments (the same case always gives the same file), so
    it is safe to run on any worker that sees ``root``.

    Parameters
    ----------
    spec_json : the case as JSON (validated here again).
    root : the result store (or its folder), as seen by the worker.
    force : recompute even if a readable result exists.

    Returns
    -------
    dict
        ``{"case_id", "status": "done" | "failed" | "cancelled", "error": str | None,
        "summary": {scalar name: float}, "warnings": [str], "computed": bool, "seconds": float}``;
        ``summary`` and ``warnings`` are empty for a failed case; ``warnings`` are the
        solver's (e.g. displacements outside the small-displacement model). Solver
        failures are returned (and recorded in the store), not raised.

    Raises
    ------
    pydantic.ValidationError
        If ``spec_json`` is not a valid case.
    """
    store = as_store(root)
    spec = CaseSpec.model_validate_json(spec_json)
    case_id = spec.case_id
    start = time.perf_counter()
    try:
        try:
            summary, warnings, computed = store.solve_or_read(spec, force=force)
        finally:
            release_memory()  # what the case freed goes back to the system, not kept for ever
    except CaseCancelled as exc:  # given up on request: neither a result nor a failure
        return {"case_id": case_id, "status": "cancelled", "error": str(exc), "summary": {}, "warnings": [],
                "computed": False, "seconds": time.perf_counter() - start}
    except Exception as exc:  # recorded in the store by solve_or_read; the sweep goes on
        return {"case_id": case_id, "status": "failed", "error": f"{type(exc).__name__}: {exc}",
                "summary": {}, "warnings": [], "computed": True, "seconds": time.perf_counter() - start}
    return {"case_id": case_id, "status": "done", "error": None, "summary": summary, "warnings": warnings,
            "computed": computed, "seconds": time.perf_counter() - start}


def map_cases(client, spec_jsons: Sequence[str], case_ids: Sequence[str], root: str, *,
              force: bool = False) -> list:
    """One :func:`solve_and_store` task per case on dask, under :func:`task_key`: how the
    CLI's sweeps (:func:`submit_cases`) and the service's dispatcher both submit cases, so a
    case has one task key whoever asks. ``root`` is the store's folder as the workers see it, or its URL.

    Cases that share a mesh and materials share the solver model built on each worker
    (:func:`solver.model.shared_model`), so no grouping of tasks is needed for that.
    """
    n = len(case_ids)
    return client.map(solve_and_store, list(spec_jsons), [root] * n, [force] * n,
                      key=[task_key(c) for c in case_ids], pure=False)


def submit_cases(client, specs: Sequence[CaseSpec], root: StoreLike, *, force: bool = False) -> dict:
    """Submit the cases ``specs`` (:func:`map_cases`); return ``{future: case id}``."""
    futures = map_cases(client, [s.named_json() for s in specs], [s.case_id for s in specs],
                        str(as_store(root)), force=force)
    return {future: spec.case_id for future, spec in zip(futures, specs)}


def outcome(future, case_id: str) -> dict:
    """The summary dict of a finished future of :func:`submit_cases`; a task that raised
    (e.g. ``KilledWorker`` after repeated worker deaths) counts as the case failing."""
    try:
        return future.result()
    except Exception as exc:
        return {"case_id": case_id, "status": "failed", "error": f"{type(exc).__name__}: {exc}", "summary": {}}
