"""Response bodies of the REST API (they are the OpenAPI schema's components)."""
from __future__ import annotations

from datetime import datetime, timezone
from typing import Literal, Optional

from fastapi import Response
from pydantic import BaseModel, Field

from .results import finite_summary, non_finite_entries
from .job_records import CaseRecord, SweepRecord

Status = Literal["queued", "running", "done", "failed", "cancelled"]
CASE_ID_PATTERN = r"^[0-9a-f]{16}$"


def _time(t: float | None) -> datetime | None:
    return None if t is None else datetime.fromtimestamp(t, tz=timezone.utc)


def json_response(model: BaseModel, status_code: int = 200, headers: Optional[dict] = None) -> Response:
    """``model`` as a JSON response, serialized once.

    A route that returns a model has FastAPI validate it against the route's
    ``response_model`` again before serializing it, work the model's construction has
    just done (with the record not read back after its insert, 8 % of ``POST /cases``'s
    CPU in process: ``python -m bench.service --cpu``). The route keeps its
    ``response_model`` for the OpenAPI schema; the bytes are the same.
    """
    return Response(content=model.model_dump_json(), status_code=status_code, media_type="application/json",
                    headers=headers)


class Case(BaseModel):
    """A case's record: what was asked and what became of it."""

    id: str = Field(description="case id: 16 hex digits of the hash of the canonical case JSON")
    status: Status
    spec: dict = Field(description="the case with every default filled in")
    summary: Optional[dict[str, Optional[float]]] = Field(
        None, description="result scalars (SPEC §3) once done; null where not finite (see non_finite)")
    non_finite: dict[str, Literal["inf", "-inf", "nan"]] = Field(
        default_factory=dict, description="the summary scalars that are not finite and what they are "
                                          "(max_utilization inf: the section fails at any load level)")
    error: Optional[str] = Field(None, description="why the case failed")
    warnings: list[str] = Field(default_factory=list, description="the solver's warnings about a done "
                                "case's result (e.g. displacements outside the small-displacement model)")
    submitted_at: datetime
    started_at: Optional[datetime] = None
    finished_at: Optional[datetime] = None
    result: Optional[str] = Field(None, description="URL of the netCDF result once done")

    @classmethod
    def of(cls, record: CaseRecord, **extra) -> "Case":
        """The record as this model (``extra``: the fields a subclass adds)."""
        return cls(
            id=record.id, status=record.status, spec=record.spec, summary=finite_summary(record.summary),
            non_finite=non_finite_entries(record.summary),
            error=record.error, warnings=list(record.warnings), submitted_at=_time(record.submitted_at),
            started_at=_time(record.started_at), finished_at=_time(record.finished_at),
            result=f"/cases/{record.id}/result.nc" if record.status == "done" else None, **extra)


class CaseAccepted(Case):
    """Answer to ``POST /cases``."""

    created: bool = Field(description="false when the case was already known (nothing recomputed)")
    input_warnings: list[str] = Field(default_factory=list, description="inputs outside their plausible range "
                                      "(e.g. a density typed in kN/m³): accepted, but most likely a mistake of units")


class CasePage(BaseModel):
    """A page of ``GET /cases``."""

    items: list[Case]
    total: int = Field(description="cases matching the filter, over all pages")
    limit: int
    offset: int


class StatusCounts(BaseModel):
    """Number of cases in each status."""

    queued: int = 0
    running: int = 0
    done: int = 0
    failed: int = 0
    cancelled: int = 0


class SweepStatus(BaseModel):
    """A sweep's record and the state of its cases."""

    id: str = Field(description="sweep id: 16 hex digits of the hash of the canonical sweep JSON")
    name: str
    case_ids: list[str] = Field(description="its cases, in expansion order")
    counts: StatusCounts
    total: int
    finished: bool = Field(description="true when no case is queued or running")
    submitted_at: datetime
    result: Optional[str] = Field(None, description="URL of the combined netCDF once a case is done")

    @classmethod
    def of(cls, record: SweepRecord, counts: dict[str, int]) -> "SweepStatus":
        return cls(
            id=record.id, name=record.name, case_ids=list(record.case_ids),
            counts=StatusCounts(**counts), total=len(record.case_ids),
            finished=counts["queued"] + counts["running"] == 0,
            submitted_at=_time(record.submitted_at),
            result=f"/sweeps/{record.id}/result.nc" if counts["done"] else None)


class SweepPage(BaseModel):
    """A page of ``GET /sweeps``, newest first."""

    items: list[SweepStatus]
    total: int = Field(description="sweeps recorded, over all pages")
    limit: int
    offset: int


class SweepCancelled(SweepStatus):
    """Answer to ``POST /sweeps/{id}/cancel``."""

    cancelled_now: list[str] = Field(description="cases this request cancelled (queued ones, and running "
                                                 "ones, whose workers give them up within a second)")


class SweepAccepted(SweepStatus):
    """Answer to ``POST /sweeps``."""

    created: bool = Field(description="false when the same sweep was posted before")
    new_cases: int = Field(description="cases not known before this request (the others are reused)")
    resubmitted: int = Field(0, description="cases recomputed by this request (retry=failed)")


class Health(BaseModel):
    """``GET /health``: 200 when everything is reachable, else 503 with the same body."""

    status: Literal["ok", "degraded"]
    reasons: list[str] = Field([], description="what is wrong when degraded")
    scheduler: Optional[str] = Field(description="scheduler address")
    scheduler_reachable: bool
    workers: int = Field(description="workers connected to the scheduler")
    results_writable: bool = Field(description="results directory and job database accept writes, "
                                               "with room for a case")
    results_free_bytes: int = Field(description="free space in the results directory (bytes)")
    queued: int
    running: int


class FieldError(BaseModel):
    """One reason a request was refused."""

    field: str = Field(description="dotted path of the offending field, e.g. 'geometry.depth'")
    reason: str
    type: str = Field(description="machine-readable error kind")


class ErrorBody(BaseModel):
    """Error responses: ``detail`` says what went wrong; ``errors`` lists invalid fields (422)."""

    detail: str
    errors: list[FieldError] = []
