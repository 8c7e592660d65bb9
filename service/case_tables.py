"""``/cases/{id}/tables.xlsx`` and ``/cases/{id}/forces.csv``: a finished case's tables in engineering
units (SPEC §9.3, :mod:`workflows.case_tables`), built on request from its stored result."""
from __future__ import annotations

import asyncio

from fastapi import APIRouter, Request, Response

from workflows.case_tables import stored_tables

from .cases import _result_of_done_case
from .errors import responses
from .params import CaseId, jobs_of, not_ready

router = APIRouter(prefix="/cases", tags=["cases"])

XLSX = "application/vnd.openxmlformats-officedocument.spreadsheetml.sheet"


async def _tables(request: Request, case_id: str, kind: str) -> bytes:
    await _result_of_done_case(request, case_id)
    jobs = jobs_of(request)
    try:
        return await asyncio.to_thread(stored_tables, jobs.root, case_id, kind)
    except Exception:
        if await jobs.recompute_broken(case_id):  # the file broke since it was checked
            raise not_ready(f"case {case_id}", "its stored result was missing or unreadable; "
                                               "it is being recomputed") from None
        raise


@router.get("/{case_id}/tables.xlsx", response_class=Response, responses={
    200: {"content": {XLSX: {}}, "description": "sheets forces (per station, characteristic and design values), "
                                                "joints, summary and inputs; a units row, engineering units"},
    **responses(404, 409)})
async def get_case_tables(case_id: CaseId, request: Request) -> Response:
    """The case's tables as an Excel workbook (3 significant figures shown, autofilter, inputs sheet)."""
    data = await _tables(request, case_id, "xlsx")
    return Response(data, media_type=XLSX, headers={"Content-Disposition": f'attachment; filename="{case_id}.xlsx"'})


@router.get("/{case_id}/forces.csv", response_class=Response, responses={
    200: {"content": {"text/csv": {}}, "description": "the lining forces per station: names, a units row, rows"},
    **responses(404, 409)})
async def get_case_forces(case_id: CaseId, request: Request) -> Response:
    """The lining forces table as CSV (every digit; engineering units named in the second row)."""
    data = await _tables(request, case_id, "csv")
    return Response(data, media_type="text/csv; charset=utf-8",
                    headers={"Content-Disposition": f'attachment; filename="{case_id}-forces.csv"'})
