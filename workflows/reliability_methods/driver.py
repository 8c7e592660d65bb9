"""The study driver: the chosen algorithm on the FE limit state, every call a stored case.

The algorithm knows only :class:`~.limit_state.LimitState`; the driver gives it one whose
points are cases solved by a *runner*: :class:`StoreRunner` on dask (the command line and
``workflows.reliability_study``) or the service's job queue. Everything random is seeded and the
cases are content-addressed, so a study run again (after a kill, a restart of the service)
replays the same points, finds their cases stored, and ends with the same answer.
"""
from __future__ import annotations

import logging
import math
import os
import time
from collections.abc import Callable, Sequence
from typing import Any, Optional

import numpy as np

from ..result_store import ResultStore, StoreLike, as_store
from .akmcs import ak_mcs
from .form import form
from .limit_state import CaseLimitState, Runner
from .records import ReliabilityRecord, new_record, read_record, write_record
from .result import ReliabilityResult, beta_of
from .study import ReliabilityStudy
from .subset import subset_simulation

logger = logging.getLogger(__name__)

ALGORITHMS = {"form": form, "subset": subset_simulation, "ak-mcs": ak_mcs}


class StoreRunner:
    """Solve cases on dask into the store; stored cases (and recorded failures) are read back,
    their ``output`` from the store's index (a study run again reads hundreds at once)."""

    def __init__(self, root: StoreLike, client, output: str):
        self.store = ResultStore(os.path.abspath(as_store(root).root))
        self.client = client
        self.output = output

    def __call__(self, specs: Sequence) -> list[dict]:
        from ..tasks import run_cases

        out, todo, stored = [], [], []
        for spec in specs:
            if self.store.is_stored(spec.case_id):
                stored.append(spec)
                continue
            error = self.store.read_error(spec.case_id)
            if error is not None:
                out.append({"case_id": spec.case_id, "status": "failed", "error": str(error.get("error", error))})
            else:
                todo.append(spec)
        if stored:
            broken = set(self.store.unreadable([s.case_id for s in stored]))
            todo += [s for s in stored if s.case_id in broken]
            readable = [s.case_id for s in stored if s.case_id not in broken]
            if readable:
                values = self.store.open_results(readable)[self.output]
                for case_id, value in zip(values["case_id"].values, values.values):
                    out.append({"case_id": str(case_id), "status": "done", "summary": {self.output: float(value)}})
        if todo:
            out.extend(run_cases(self.client, todo, self.store))
        return out


def answer(study: ReliabilityStudy, g: CaseLimitState, result: ReliabilityResult) -> dict[str, Any]:
    """The result in the study's terms: variables by path, the design point's case."""
    u = result.design_point
    design_case = None
    if u is not None:
        key = g.key(u)
        design_case = key if key in g.outputs else None
    importance = result.importance
    beta_ci = None
    if result.method == "form":
        beta_ci = [beta_of(result.ci_high), beta_of(result.ci_low)] if np.isfinite(result.ci_low) else None
    elif result.converged:
        beta_ci = [beta_of(result.ci_high), beta_of(result.ci_low)]

    def finite(x):
        return None if x is None or not math.isfinite(x) else float(x)

    return {
        "method": result.method, "beta": finite(result.beta), "beta_ci": beta_ci,
        "probability": finite(result.probability), "ci_low": finite(result.ci_low), "ci_high": finite(result.ci_high),
        "cov": finite(result.cov),
        "design_point": g.values(u) if u is not None else None, "design_case": design_case,
        "importance": dict(zip(study.paths, map(float, importance))) if importance is not None else None,
        "calls": g.calls, "budget": study.budget, "converged": result.converged, "note": result.note,
        "history": result.history, "details": result.details, "case_ids": list(g.keys),
    }


def run_study(study: ReliabilityStudy | dict, runner: Runner, *,
              on_progress: Optional[Callable[[dict], None]] = None) -> dict[str, Any]:
    """The study's answer (see :func:`answer`), its FE calls made by ``runner``."""
    study = ReliabilityStudy.model_validate(study)
    g = CaseLimitState(study, runner)
    options: dict[str, Any] = {"seed": study.seed}
    if study.method == "subset" and study.samples_per_level:
        options["samples"] = study.samples_per_level

    def progress(step: dict) -> None:
        if on_progress:
            on_progress({**step, "calls": g.calls})

    result = ALGORITHMS[study.method](g, on_progress=progress, **options)
    return answer(study, g, result)


def recorder(root: StoreLike, record: ReliabilityRecord, *, every: float = 0.5) -> Callable[[dict], None]:
    """An ``on_progress`` that keeps the study's record up to date (at most every ``every`` s)."""
    state = {"record": record, "last": 0.0}

    def on_progress(step: dict) -> None:
        rec = state["record"]
        rec = rec.model_copy(update={"calls": step.get("calls", rec.calls), "stage": step.get("stage"),
                                     "history": rec.history + [step]})
        state["record"] = rec
        now = time.monotonic()
        if now - state["last"] >= every:
            state["last"] = now
            write_record(root, rec)

    return on_progress


def finished(record: ReliabilityRecord, result: dict) -> ReliabilityRecord:
    return record.model_copy(update={**{k: v for k, v in result.items() if k in ReliabilityRecord.model_fields},
                                     "status": "done", "stage": "done", "finished_at": time.time()})


def reliability_study(study: ReliabilityStudy | dict, root: StoreLike, client=None, *,
                      progress: bool = False) -> dict[str, Any]:
    """Run the reliability study ``study`` (SPEC §9.6) on dask and return its answer:
    ``beta``, ``probability``, ``ci_low``, ``ci_high``, ``design_point`` {path: value},
    ``design_case``, ``importance`` {path: α²}, ``calls`` (every one a stored case) and the
    convergence ``history``. Run again, it resumes: its cases are found stored.

    ``client``: a ``distributed.Client``; None starts an embedded LocalCluster.
    """
    from ..sweep import _client_or_local

    study = ReliabilityStudy.model_validate(study)
    store = as_store(root)
    record = read_record(store, study.study_id)
    record = new_record(study) if record is None else record.model_copy(
        update={"status": "running", "history": [], "error": None})
    write_record(store, record)
    on_progress = recorder(store, record)
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=study.budget, desc=f"reliability {study.name}", unit="call")

    def show(step: dict) -> None:
        on_progress(step)
        if bar is not None:
            bar.update(step["calls"] - bar.n)

    try:
        with _client_or_local(client) as c:
            result = run_study(study, StoreRunner(store, c, study.output), on_progress=show)
    except Exception as exc:
        write_record(store, record.model_copy(update={"status": "failed", "error": f"{type(exc).__name__}: {exc}",
                                                      "finished_at": time.time()}))
        raise
    finally:
        if bar is not None:
            bar.close()
    write_record(store, finished(record, result))
    return {"id": study.study_id, "name": study.name, **result}
