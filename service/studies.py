"""``/sweeps`` as studies: the list, the comparison table (JSON, CSV), sweep plots, cancel.

The dashboard's pages (:mod:`service.pages`) call these same functions.
"""
from __future__ import annotations

import asyncio
from enum import Enum

from fastapi import APIRouter, Depends, Query, Request
from fastapi.responses import FileResponse, Response

from workflows.artifacts import render_sweep_plot
from workflows.plots import SWEEP_PLOT_NAMES

from .comparison import ComparisonTable, comparison_table, table_csv, table_xlsx
from .errors import responses
from .guards import require_token
from .params import Offset, SweepId, jobs_of, sweep_or_404, sweep_results
from .schemas import SweepCancelled, SweepPage, SweepStatus

router = APIRouter(prefix="/sweeps", tags=["sweeps"])

#: Plot names accepted in ``/sweeps/{id}/plots/{name}.png``.
SweepPlotName = Enum("SweepPlotName", {name: name for name in SWEEP_PLOT_NAMES}, type=str)


@router.get("", response_model=SweepPage, responses=responses(422))
async def list_sweeps(request: Request, limit: int = Query(20, ge=1, le=200),
                      offset: Offset = 0) -> SweepPage:
    """Sweeps, newest submission first, a page at a time, each with its counts by status."""
    store = jobs_of(request).store
    records, total = store.list_sweeps(limit=limit, offset=offset)
    counts = store.sweep_status_counts([r.id for r in records])
    return SweepPage(items=[SweepStatus.of(r, counts[r.id]) for r in records],
                     total=total, limit=limit, offset=offset)


@router.get("/{sweep_id}/table", response_model=ComparisonTable, responses=responses(404))
async def get_sweep_table(sweep_id: SweepId, request: Request) -> ComparisonTable:
    """The comparison table: one row per case; columns ``case_id``, ``status``, the parameters
    that vary across the sweep, the result scalars (SI units; see ``columns``), then ``error``
    and ``warnings``."""
    return comparison_table(jobs_of(request).store, sweep_or_404(request, sweep_id))


@router.get("/{sweep_id}/summary.csv", response_class=Response, responses={
    200: {"content": {"text/csv": {}},
          "description": "header row, then one row per case in sweep order: case_id, status, the "
                         "varied parameters (flat names, e.g. lining_thickness), the result "
                         "scalars of SPEC §3 in SI units (empty until the case is done), then "
                         "error (why a case failed) and warnings (the solver's, about a result)"},
    **responses(404)})
async def get_sweep_csv(sweep_id: SweepId, request: Request) -> Response:
    """The comparison table as CSV (the same columns as ``/sweeps/{id}/table``)."""
    table = await get_sweep_table(sweep_id, request)
    return Response(table_csv(table), media_type="text/csv; charset=utf-8",
                    headers={"Content-Disposition": f'attachment; filename="sweep-{sweep_id}.csv"'})


XLSX = "application/vnd.openxmlformats-officedocument.spreadsheetml.sheet"


@router.get("/{sweep_id}/summary.xlsx", response_class=Response, responses={
    200: {"content": {XLSX: {}},
          "description": "the comparison table as a workbook: a row of column names, a row of units "
                         "(engineering units: kPa, kN/m, mm, ...), then one row per case"},
    **responses(404)})
async def get_sweep_xlsx(sweep_id: SweepId, request: Request) -> Response:
    """The comparison table as an Excel workbook in engineering units with a units row."""
    table = await get_sweep_table(sweep_id, request)
    return Response(table_xlsx(table), media_type=XLSX,
                    headers={"Content-Disposition": f'attachment; filename="sweep-{sweep_id}.xlsx"'})


@router.get("/{sweep_id}/plots/{name}.png", response_class=FileResponse, responses={
    200: {"content": {"image/png": {}},
          "description": "the figure over the sweep's finished cases (header X-Cases-Included)"},
    **responses(404, 409)})
async def get_sweep_plot(sweep_id: SweepId, name: SweepPlotName, request: Request) -> FileResponse:
    """A figure of the sweep's finished cases: ``contact_pressure``, ``lining_forces``,
    ``interaction`` (N–M stations of every case, with design envelopes when the results
    have them) or ``scalars`` (each summary scalar against each varied parameter).
    As for ``result.nc``: 409 while no case is done but some is open, 404 when none can be."""
    jobs = jobs_of(request)
    record = sweep_or_404(request, sweep_id)
    done = await sweep_results(jobs, record)  # as for result.nc
    path = await asyncio.to_thread(render_sweep_plot, jobs.root, sweep_id, done, name.value)
    return FileResponse(path, media_type="image/png",
                        headers={"X-Cases-Included": f"{len(done)}/{len(record.case_ids)}"})


@router.post("/{sweep_id}/cancel", response_model=SweepCancelled,
             dependencies=[Depends(require_token)], responses=responses(401, 404))
async def cancel_sweep(sweep_id: SweepId, request: Request) -> SweepCancelled:
    """Cancel the sweep's queued and running cases (they become ``cancelled``; a running one's
    worker gives it up within about a second, no result and no error recorded).

    Posting the sweep (or one of its cases) again submits the cancelled cases again.
    """
    jobs = jobs_of(request)
    record = sweep_or_404(request, sweep_id)
    cancelled = await jobs.cancel(list(record.case_ids))
    status = SweepStatus.of(record, jobs.store.status_counts(record.case_ids))
    return SweepCancelled(**status.model_dump(), cancelled_now=cancelled)
