"""The dask task: one case in, a small summary out (no field arrays cross the wire).

:func:`task_key` names the task of a case for every submitter (the service, and the command
line's sweeps for a case alone in its task), so on a shared scheduler a case submitted twice runs
once. The command line's sweeps hand cheap cases out several to a task (:func:`run_cases`).
"""
from __future__ import annotations

import json
import logging
import math
import time
from collections import deque
from collections.abc import Iterator, Sequence

from solver.limits import CaseCancelled
from solver.spec import CaseSpec, content_id

from .result_store import StoreLike, as_store
from .workers import release_memory

logger = logging.getLogger(__name__)

#: Prefix of the dask key of a case's task; the rest is the case id.
TASK_KEY_PREFIX = "solve_and_store-"
#: Prefix of the dask key of a task solving several cases in turn (:func:`run_cases`).
BATCH_KEY_PREFIX = "solve_and_store_each-"
#: Seconds of solving a task of :func:`run_cases` holds (by its cases' measured seconds). A task of
#: one case cost the process of the client and the scheduler 3.5-4 ms of CPU and its worker 2-3 ms
#: more (a coarse sweep on two workers): a fifth of a coarse case's 32 ms, on the same two cores.
BATCH_SECONDS = 1.0
#: Most cases in one task of :func:`run_cases`.
MAX_BATCH = 32


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
    try:
        return _solved(spec_json, root, force)
    finally:
        release_memory()  # what the case freed goes back to the system, not kept for ever


def _solved(spec_json: str, root: StoreLike, force: bool) -> dict:
    """:func:`solve_and_store` but for the memory released."""
    store = as_store(root)
    spec = CaseSpec.model_validate_json(spec_json)
    case_id = spec.case_id
    start = time.perf_counter()
    try:
        summary, warnings, computed = store.solve_or_read(spec, force=force)
    except CaseCancelled as exc:  # given up on request: neither a result nor a failure
        return {"case_id": case_id, "status": "cancelled", "error": str(exc), "summary": {}, "warnings": [],
                "computed": False, "seconds": time.perf_counter() - start}
    except Exception as exc:  # recorded in the store by solve_or_read; the sweep goes on
        return {"case_id": case_id, "status": "failed", "error": f"{type(exc).__name__}: {exc}",
                "summary": {}, "warnings": [], "computed": True, "seconds": time.perf_counter() - start}
    return {"case_id": case_id, "status": "done", "error": None, "summary": summary, "warnings": warnings,
            "computed": computed, "seconds": time.perf_counter() - start}


def solve_and_store_each(spec_jsons: Sequence[str], case_ids: Sequence[str], root: StoreLike,
                         force: bool = False) -> list[dict]:
    """:func:`solve_and_store` of each case in turn, in one task: their summary dicts, in order.
    A case that raises (not a valid case) is that case's failure, not the others'. The memory
    is released once, after the last case (counting glibc's free bytes took 0.7 ms a case in a
    worker, 2 % of a coarse case)."""
    out = []
    try:
        for spec_json, case_id in zip(spec_jsons, case_ids):
            try:
                out.append(_solved(spec_json, root, force))
            except Exception as exc:
                out.append(_failure(case_id, exc))
    finally:
        release_memory()
    return out


def map_cases(client, spec_jsons: Sequence[str], case_ids: Sequence[str], root: str, *,
              force: bool = False) -> list:
    """One :func:`solve_and_store` task per case on dask, under :func:`task_key`: how the
    service's dispatcher submits cases, and :func:`run_cases` a case alone, so a case has one
    task key whoever asks. ``root`` is the store's folder as the workers see it, or its URL.

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
        return _failure(case_id, exc)


def _failure(case_id: str, exc: BaseException) -> dict:
    return {"case_id": case_id, "status": "failed", "error": f"{type(exc).__name__}: {exc}", "summary": {}}


def run_cases(client, specs: Sequence[CaseSpec], root: StoreLike, *, force: bool = False) -> Iterator[dict]:
    """Solve ``specs`` on dask; yield each case's summary dict (:func:`solve_and_store`) as its
    task ends, in the order they end.

    Cases go several to a task (:func:`solve_and_store_each`) when they are cheap: about
    :data:`BATCH_SECONDS` of solving by the seconds the cases so far took, one a task until the
    first has ended, fewer towards the end so that the workers finish together. Two tasks per
    worker thread are out at a time, so a worker has its next task when it ends one. A case
    alone in its task runs under its :func:`task_key`; the cases of a task that raised (its
    worker died) are tried again one a task, so a case that kills its worker fails alone.
    """
    from distributed import as_completed

    root = str(as_store(root))
    waiting = deque(specs)
    slots = 2 * max(1, sum(client.nthreads().values()))
    running = as_completed()
    batches: dict = {}
    per_case = [math.inf]  # seconds a case of the last task took

    def submit(batch: list[CaseSpec]) -> None:
        jsons, ids = [s.named_json() for s in batch], [s.case_id for s in batch]
        if len(batch) == 1:
            future = map_cases(client, jsons, ids, root, force=force)[0]
        else:
            key = BATCH_KEY_PREFIX + content_id(json.dumps([ids, force]))
            future = client.submit(solve_and_store_each, jsons, ids, root, force, key=key, pure=False)
        batches[future] = batch
        running.add(future)

    def submit_next() -> None:
        size = min(MAX_BATCH, math.ceil(len(waiting) / (2 * slots)),
                   int(BATCH_SECONDS / per_case[0]) if per_case[0] > 0 else MAX_BATCH)
        submit([waiting.popleft() for _ in range(max(1, size))])

    while waiting and len(batches) < slots:
        submit_next()
    for future in running:
        batch = batches.pop(future)
        try:
            result = future.result()
        except Exception as exc:
            if len(batch) > 1:
                logger.warning("a task of %d cases raised %s; trying them one a task", len(batch), type(exc).__name__)
                for spec in batch:
                    submit([spec])
                continue
            result = _failure(batch[0].case_id, exc)
        results = result if isinstance(result, list) else [result]
        per_case[0] = sum(r.get("seconds") or 0.0 for r in results) / len(results)
        if waiting:
            submit_next()
        yield from results
