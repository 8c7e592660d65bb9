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
from workflows.studies import StudyError, reliability, sensitivity

from .comparison import ComparisonTable, comparison_table, table_csv, table_parquet, table_xlsx
from .errors import invalid, responses
from .guards import require_token
from .params import Offset, SweepId, build_over_results, jobs_of, sweep_or_404
from .schemas import FieldError, SweepCancelled, SweepPage, SweepStatus

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
          "description": "header row, units row (engineering units: mm, MPa, kPa, kN/m, ...), then one "
                         "row per case in sweep order: case_id, status, the varied parameters (flat "
                         "names, e.g. lining_thickness), the result scalars of SPEC §3 in the units "
                         "of the units row (empty until the case is done), then error (why a case "
                         "failed) and warnings (the solver's, about a result)"},
    **responses(404)})
async def get_sweep_csv(sweep_id: SweepId, request: Request) -> Response:
    """The comparison table as CSV (the same columns as ``/sweeps/{id}/table``), in engineering
    units with a units row under the header, as ``summary.xlsx``."""
    table = await get_sweep_table(sweep_id, request)
    return Response(table_csv(table), media_type="text/csv; charset=utf-8",
                    headers={"Content-Disposition": f'attachment; filename="sweep-{sweep_id}.csv"'})


PARQUET = "application/vnd.apache.parquet"


@router.get("/{sweep_id}/table.parquet", response_class=Response, responses={
    200: {"content": {PARQUET: {}},
          "description": "the study table as Parquet, one row per case in sweep order: case_id, status, "
                         "name (the sweep's), the varied parameters, the result scalars (float64, SI "
                         "units in each field's metadata; null until the case is done), error, warnings"},
    **responses(404)})
async def get_sweep_parquet(sweep_id: SweepId, request: Request) -> Response:
    """The study table (the columns of ``/sweeps/{id}/table`` and ``name``) as Parquet, for
    pandas, polars, DuckDB or Spark: ``pandas.read_parquet(url)``."""
    record = sweep_or_404(request, sweep_id)
    table = comparison_table(jobs_of(request).store, record)
    body = await asyncio.to_thread(table_parquet, table, record.name)
    return Response(body, media_type=PARQUET,
                    headers={"Content-Disposition": f'attachment; filename="sweep-{sweep_id}.parquet"'})


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
    done, path = await build_over_results(  # as for result.nc
        jobs, record, lambda ids: render_sweep_plot(jobs.root, sweep_id, ids, name.value))
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


# -- analyses (SPEC §8) --------------------------------------------------------------------------

#: Sweep modes whose cases are a random sample of the varied parameters' distributions.
RANDOM_MODES = ("sobol", "lhs", "random")


def _study_error(exc: StudyError):
    """Bad input (an unknown output): 422; too few done cases: 409 (the sweep is not ready)."""
    if any(field == "case_ids" for field, _ in exc.errors):
        return invalid([FieldError(field="sweep", reason=r, type="not_ready") for _, r in exc.errors], 409)
    return invalid([FieldError(field=f, reason=r, type="value_error") for f, r in exc.errors])


async def _analysis(request: Request, sweep_id: str, fn, *args):
    jobs = jobs_of(request)
    record = sweep_or_404(request, sweep_id)
    try:
        return record, await asyncio.to_thread(fn, jobs.root, list(record.case_ids), *args)
    except StudyError as exc:
        return record, _study_error(exc)


def _sensitivity_body(ds) -> dict:
    def num(v):
        v = float(v)
        return None if v != v else v
    return {"output": ds.attrs["output"], "method": ds.attrs["method"], "samples": int(ds.attrs["samples"]),
            "not_done": int(ds.attrs["not_done"]), "noise_floor": float(ds.attrs["noise_floor"]),
            "parameters": [{"parameter": str(p), **{k: num(ds[k].values[i]) for k in
                            ("first_order", "first_order_ci", "total_order", "total_order_ci")}}
                           for i, p in enumerate(ds["parameter"].values)]}


def _png(fig) -> Response:
    from workflows.study_plots import png

    return Response(png(fig), media_type="image/png")


@router.get("/{sweep_id}/sensitivity", responses=responses(404, 409, 422))
async def get_sensitivity(sweep_id: SweepId, request: Request, output: str = Query(..., examples=["max_abs_moment"])):
    """Global sensitivity of the result scalar ``output`` to each parameter the sweep varies:
    first-order and total indices with 95 % half-widths (SALib's HDMR on the sweep's own
    sample from 300 done cases; below, the delta method's first-order index alone, the
    total ``null``, and ``noise_floor``: a dummy parameter's index, below which an index
    cannot be told from zero). 409 while fewer than 128 cases are done."""
    _, ds = await _analysis(request, sweep_id, sensitivity, output)
    return ds if isinstance(ds, Response) else _sensitivity_body(ds)


@router.get("/{sweep_id}/sensitivity.png", response_class=Response,
            responses={200: {"content": {"image/png": {}}}, **responses(404, 409, 422)})
async def get_sensitivity_plot(sweep_id: SweepId, request: Request, output: str = Query(...)) -> Response:
    """The sensitivity indices as bars with their intervals."""
    from workflows.study_plots import plot_sensitivity

    _, ds = await _analysis(request, sweep_id, sensitivity, output)
    return ds if isinstance(ds, Response) else await asyncio.to_thread(lambda: _png(plot_sensitivity(ds)))


def _reliability_body(record, r: dict) -> dict:
    """The reliability answer without its sample; for a sweep that samples no distribution (a grid
    or a zip) no β (``null``: the fraction above the limit is no probability) and a note saying so."""
    body = {k: v for k, v in r.items() if k != "values"}
    if record.spec.get("mode", "grid") not in RANDOM_MODES:
        body.update(beta=None, beta_ci=[None, None])
        body["note"] = " ".join(filter(None, [
            f"the sweep is a {record.spec.get('mode', 'grid')}, not a random sample of the uncertain parameters: "
            "the fraction of its cases above the limit is not a probability (no β)", body.get("note")]))
    return body


@router.get("/{sweep_id}/reliability", responses=responses(404, 409, 422))
async def get_reliability(sweep_id: SweepId, request: Request, output: str = Query("max_utilization"),
                          limit: float = Query(1.0, allow_inf_nan=False)):
    """Probability that ``output`` exceeds ``limit`` over the sweep's done cases, its exact
    (Clopper–Pearson) 95 % interval and β = -Φ⁻¹(P) (``null`` at P = 0 or 1, and for a sweep that is
    no random sample: a grid or a zip); ``note`` says when the estimate rests on few cases or the
    sweep is not a random sample."""
    record, r = await _analysis(request, sweep_id, reliability, output, limit)
    return r if isinstance(r, Response) else _reliability_body(record, r)


@router.get("/{sweep_id}/reliability.png", response_class=Response,
            responses={200: {"content": {"image/png": {}}}, **responses(404, 409, 422)})
async def get_reliability_plot(sweep_id: SweepId, request: Request, output: str = Query("max_utilization"),
                               limit: float = Query(1.0, allow_inf_nan=False)) -> Response:
    """The output's distribution over the cases with the limit and the probability above it."""
    from workflows.study_plots import plot_reliability

    record, r = await _analysis(request, sweep_id, reliability, output, limit)
    if isinstance(r, Response):
        return r
    r = {**r, **_reliability_body(record, r)}  # a grid's: no β, and the note saying why
    return await asyncio.to_thread(lambda: _png(plot_reliability(r)))
