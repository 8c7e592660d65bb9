"""A study's record: a JSON file ``reliability/<id>.json`` in the results store, written
atomically; the command line and the service write the same record, so the dashboard shows a
study whoever ran it. The record is a view: the truth is the stored cases, from which a study
run again rebuilds its answer."""
from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import Any, Optional

from pydantic import BaseModel

from ..files import write_atomically
from ..result_store import StoreLike, as_store

logger = logging.getLogger(__name__)

FOLDER = "reliability"


class ReliabilityRecord(BaseModel):
    """A study's progress and, once done, its answer (SPEC §9.6)."""

    id: str
    name: str
    study: dict[str, Any]
    status: str = "running"  # running, done, failed
    calls: int = 0
    budget: int = 0
    stage: Optional[str] = None
    beta: Optional[float] = None
    beta_ci: Optional[list[Optional[float]]] = None
    probability: Optional[float] = None
    ci_low: Optional[float] = None
    ci_high: Optional[float] = None
    cov: Optional[float] = None
    design_point: Optional[dict[str, float]] = None
    design_case: Optional[str] = None
    importance: Optional[dict[str, float]] = None
    converged: Optional[bool] = None
    note: Optional[str] = None
    history: list[dict[str, Any]] = []
    details: dict[str, Any] = {}
    case_ids: list[str] = []
    error: Optional[str] = None
    submitted_at: float = 0.0
    finished_at: Optional[float] = None


def record_path(root: StoreLike, ident: str) -> Path:
    return Path(as_store(root).root) / FOLDER / f"{ident}.json"


def read_record(root: StoreLike, ident: str) -> Optional[ReliabilityRecord]:
    """The study's record (on object storage: its current object), None if there is none."""
    path = record_path(root, ident)
    try:
        if not as_store(root).fetched(path):
            return None
        return ReliabilityRecord.model_validate_json(path.read_text())
    except FileNotFoundError:
        return None


def write_record(root: StoreLike, record: ReliabilityRecord) -> None:
    """Write the record (on object storage: publish it, so every replica reads it); a finished study's
    design case loses its cached report, which is written again saying that the case is a design point."""
    path = record_path(root, record.id)
    write_atomically(path, lambda tmp: tmp.write_text(record.model_dump_json(indent=1)))
    as_store(root).publish(path)
    if record.status == "done" and record.design_case:
        (as_store(root).plot_dir(record.design_case) / "report.pdf").unlink(missing_ok=True)


def all_records(root: StoreLike) -> list[ReliabilityRecord]:
    """Every study of the store, newest first (an unreadable record is logged and skipped; on object
    storage the records' objects are synced first)."""
    store = as_store(root)
    folder = Path(store.root) / FOLDER
    if store.url:
        store.remote.sync_folder(folder)
    out = []
    for p in sorted(folder.glob("*.json")):
        try:
            out.append(ReliabilityRecord.model_validate_json(p.read_text()))
        except (OSError, ValueError) as exc:
            logger.warning("reliability record %s unreadable: %s", p.name, exc)
    return sorted(out, key=lambda r: -r.submitted_at)


def new_record(study) -> ReliabilityRecord:
    return ReliabilityRecord(id=study.study_id, name=study.name, study=study.model_dump(mode="json"),
                             budget=study.budget, submitted_at=time.time())


def design_point_of(root: StoreLike, case_id: str) -> list[ReliabilityRecord]:
    """The finished reliability studies whose design point is the case ``case_id``."""
    store = as_store(root)
    if not store.url and not (Path(store.root) / FOLDER).is_dir():
        return []
    return [r for r in all_records(store) if r.design_case == case_id and r.status == "done"]


def design_point_notes(root: StoreLike, case_id: str) -> list[str]:
    """What a case's report says when the case is the design point of finished studies."""
    return [f"Design point of reliability study '{r.name}' ({r.id}): {r.study.get('method')}, "
            f"beta = {r.beta:.3f}, P = {r.probability:.3g}" if r.beta is not None and r.probability is not None
            else f"Design point of reliability study '{r.name}' ({r.id})"
            for r in design_point_of(root, case_id)]
