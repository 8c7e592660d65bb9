"""What the ``tunnel-contact`` commands do (``service/cli.py`` only parses arguments).

Each command writes its human-readable report to ``out`` and returns an exit code.
Bad input (unreadable or invalid JSON, a malformed or unknown case id) raises
:class:`InputError` with a one-line message; the CLI prints it and exits with 2.
"""
from __future__ import annotations

import json
import logging
import os
import shutil
import sys
from pathlib import Path
from typing import Any, TextIO

import xarray as xr
from pydantic import ValidationError

from solver import CaseSpec, SolverError
from solver.errors import field_errors, format_errors
from solver.spec import is_number

from .joint_check import joint_report
from .joint_plots import has_joints
from .parameters import flat_parameters, parameter_attrs
from .result_store import ResultStore, case_warnings, check_case_id
from .summary import summarize
from .sweep import Sweep, SweepError, run_sweep
# the tables live in workflows.tables; their names stay importable from here, the commands' module
from .tables import (JOINT_TABLE_COLUMNS, TABLE_COLUMNS, case_row, case_rows, column_unit,  # noqa: F401
                     comparison_table, format_summary, utilization_report, with_unit)


def configure_logging(verbose: int = 0) -> None:
    """Logging for the command line: warnings by default, ``-v`` info, ``-vv`` debug.

    dask's loggers stay at warning level unless ``verbose >= 2`` (distributed would
    otherwise log every connection at info level).
    """
    import dask

    level = (logging.WARNING, logging.INFO, logging.DEBUG)[min(verbose, 2)]
    logging.basicConfig(level=level, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    dask_level = level if verbose >= 2 else logging.WARNING
    dask.config.set({"logging.distributed": logging.getLevelName(dask_level).lower()})
    logging.getLogger("distributed").setLevel(dask_level)  # in case it is already imported


class InputError(ValueError):
    """Bad user input; the message is one line."""


def load_case(path: str | os.PathLike | None) -> CaseSpec:
    """The case in JSON file ``path`` (``None``: the default case)."""
    if path is None:
        return CaseSpec()
    data = _read_json(path)
    try:
        return CaseSpec.model_validate(data)
    except ValidationError as exc:
        raise InputError(f"{path}: invalid case: {_one_line(exc)}") from None


def load_sweep(path: str | os.PathLike) -> Sweep:
    """The sweep in JSON file ``path`` (structure only; see :func:`expand_sweep`)."""
    data = _read_json(path)
    try:
        return Sweep.model_validate(data)
    except ValidationError as exc:
        raise InputError(f"{path}: invalid sweep: {_one_line(exc)}") from None


def _read_json(path: str | os.PathLike) -> Any:
    try:
        return json.loads(Path(path).read_text())
    except OSError as exc:
        raise InputError(f"{path}: cannot read: {exc.strerror or exc}") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: not valid JSON: {exc}") from None


def _one_line(exc: ValidationError) -> str:
    return format_errors(field_errors(exc))


def run_command(case_file: str | None, results: str, *, force: bool = False, retry_failed: bool = False,
                out: TextIO | None = None) -> int:
    """Solve one case into the store and print its summary; 1 if the solver fails.

    As in the service, a case that failed before is reported, not recomputed, unless
    ``retry_failed``; a stored result that cannot be read is recomputed.
    """
    out = out or sys.stdout
    spec = load_case(case_file)
    store = ResultStore(results)
    if not force and not retry_failed and not store.is_stored(spec.case_id):
        error = store.read_error(spec.case_id)
        if error is not None:
            print(f"case {spec.case_id} failed before: {error['error']} (--retry-failed recomputes it)", file=out)
            return 1
    try:  # a stored result that cannot be read is computed again, never shown
        summary, _, _ = store.solve_or_read(spec, force=force)
    except SolverError as exc:
        print(f"case {spec.case_id} failed: {exc}", file=out)
        return 1
    print(f"case {spec.case_id} stored in {store.case_path(spec.case_id)}", file=out)
    print(format_summary(summary), file=out)
    return 0


def sweep_command(sweep_file: str, results: str, *, scheduler: str | None = None,
                  progress: bool = True, retry_failed: bool = False, out: TextIO | None = None) -> int:
    """Run a sweep on dask (``scheduler`` address or an embedded cluster); print a table.

    Cases that failed before keep their recorded failure unless ``retry_failed`` (as
    ``run``). Returns 1 if any case failed, else 0.
    """
    out = out or sys.stdout
    sweep = load_sweep(sweep_file)
    client = _scheduler_client(scheduler)
    try:
        case_ids = run_sweep(sweep, ResultStore(results), client=client, progress=progress,
                             retry_failed=retry_failed)
    except SweepError as exc:
        raise InputError(f"{sweep_file}: {exc}") from None
    finally:
        if client is not None:
            client.close()
    rows = case_rows(ResultStore(results), case_ids)
    print(comparison_table(rows), file=out)
    failed = [r for r in rows if r["status"] != "done"]
    print(f"{len(rows) - len(failed)} of {len(rows)} cases done; results in {results}", file=out)
    return 1 if failed else 0


def _scheduler_client(scheduler: str | None):
    if not scheduler:
        return None
    from distributed import Client

    return Client(scheduler, timeout="10s")


def search_command(search_file: str, results: str, *, scheduler: str | None = None, progress: bool = True,
                   out: TextIO | None = None) -> int:
    """Run a search (SPEC §8) and print its trials and answer; 1 if no value satisfies."""
    out = out or sys.stdout
    from .studies import Search, run_search

    try:
        search = Search.model_validate(_read_json(search_file))
    except ValidationError as exc:
        raise InputError(f"{search_file}: {_one_line(exc)}") from None
    client = _scheduler_client(scheduler)
    try:
        found = run_search(search, ResultStore(results), client, progress=progress)
    finally:
        if client is not None:
            client.close()
    need = search.require
    bound = f"<= {need.at_most:g}" if need.at_most is not None else f">= {need.at_least:g}"
    print(f"{'trial':>5} {search.parameter:>22} {'worst ' + need.output:>26} {'failed':>6}  meets {bound}", file=out)
    for k, t in enumerate(found["trials"], 1):
        worst = "-" if t["worst"] is None else f"{t['worst']:.5g}"
        print(f"{k:>5} {t['value']:>22.6g} {worst:>26} {t['failed']:>6}  {'yes' if t['satisfied'] else 'no'}", file=out)
    cases = found["grid_cases"]
    if found["value"] is None:
        print(f"no value of {search.parameter} in [{search.low:g}, {search.high:g}] meets {need.output} {bound}",
              file=out)
        return 1
    print(f"smallest {search.parameter} meeting {need.output} {bound} over {len(found['trials'][0]['case_ids'])} "
          f"cases: {found['value']:.6g} (to {search.tolerance:g}); {cases['search']} cases solved against "
          f"{cases['grid']} for a grid of that resolution", file=out)
    return 0


def analyse_command(sweep_id: str, results: str, *, sensitivity: str | None = None,
                    reliability: str | None = None, limit: float = 1.0, out: TextIO | None = None) -> int:
    """Print a stored sweep's sensitivity or reliability analysis (SPEC §8)."""
    out = out or sys.stdout
    from . import studies

    store = ResultStore(results)
    matches = [r for r in store.sweep_records() if r["id"].startswith(sweep_id)]
    if len(matches) != 1:
        raise InputError(f"sweep {sweep_id!r}: {'no' if not matches else 'more than one'} stored sweep has that id")
    record = matches[0]
    try:
        if sensitivity:
            ds = studies.sensitivity(store, record["case_ids"], sensitivity)
            print(f"sensitivity of {sensitivity} ({ds.attrs['samples']} cases, {ds.attrs['method']}):", file=out)
            print(f"{'parameter':>28} {'first order':>18} {'total':>18}", file=out)
            for i, name in enumerate(ds["parameter"].values):
                cells = [f"{ds[k].values[i]:.3f} ± {ds[k + '_ci'].values[i]:.3f}" for k in ("first_order", "total_order")]
                print(f"{name:>28} {cells[0]:>18} {cells[1]:>18}", file=out)
        else:
            r = studies.reliability(store, record["case_ids"], reliability or "max_utilization", limit)
            beta = "-" if r["beta"] is None else f"{r['beta']:.3f}"
            print(f"P({r['output']} > {limit:g}) = {r['probability']:.4g}, 95 % [{r['ci_low']:.4g}, "
                  f"{r['ci_high']:.4g}], beta = {beta}; {r['exceedances']} of {r['samples']} cases", file=out)
            if r["note"]:
                print(f"note: {r['note']}", file=out)
    except studies.StudyError as exc:
        raise InputError(str(exc)) from None
    return 0


def known_case_ids(store: ResultStore) -> list[str]:
    """Every case the store knows: stored results and failed cases (error records), sorted."""
    failed = {p.name[:-len(".error.json")] for p in store.cases_dir.glob("*.error.json")} \
        if store.cases_dir.is_dir() else set()
    return sorted(set(store.case_ids()) | failed)


def resolve_case_id(store: ResultStore, text: str) -> str:
    """The full case id of an id or a unique prefix of one (at least 4 hex digits)."""
    text = text.strip().lower()
    if len(text) == 16:
        try:
            return check_case_id(text)
        except ValueError as exc:
            raise InputError(str(exc)) from None
    if not 4 <= len(text) < 16 or any(ch not in "0123456789abcdef" for ch in text):
        raise InputError(f"case id {text!r}: a case id is 16 lowercase hex digits; give it or a unique prefix of at least 4")
    matches = [c for c in known_case_ids(store) if c.startswith(text)]
    if not matches:
        raise InputError(f"no case id in {store.root} starts with {text!r}")
    if len(matches) > 1:
        raise InputError(f"case id prefix {text!r} is ambiguous: {', '.join(matches[:8])}"
                         + (" ..." if len(matches) > 8 else ""))
    return matches[0]


def list_command(results: str, *, out: TextIO | None = None) -> int:
    """Print every case of the store (done and failed) as the comparison table."""
    out = out or sys.stdout
    store = ResultStore(results)
    ids = known_case_ids(store)
    if not ids:
        print(f"no cases in {results}", file=out)
        return 0
    print(comparison_table(case_rows(store, ids)), file=out)
    print(f"{len(ids)} cases in {results}", file=out)
    return 0


def show_command(case_id: str, results: str, *, out: TextIO | None = None) -> int:
    """Print a stored case's summary and write its plots to ``<results>/plots/<case_id>/``;
    ``case_id`` may be a unique prefix of the id."""
    out = out or sys.stdout
    from .artifacts import render_plot
    from .plots import PLOTS

    store = ResultStore(results)
    case_id = resolve_case_id(store, case_id)
    ds = _open_stored(store, case_id, results, out)
    if ds is None:
        return 1
    params = flat_parameters(ds.attrs["case_spec"])
    print(f"case {case_id}", file=out)
    print("\n".join(f"  {k} = {with_unit(v, parameter_attrs(k, numeric=is_number(v)).get('units'))}"
                    for k, v in params.items()), file=out)
    print(format_summary(summarize(ds)), file=out)
    if "utilization" in ds:
        print(utilization_report(ds), file=out)
    if has_joints(ds):
        print(joint_report(ds), file=out)
    for warning in case_warnings(ds):
        print(f"warning: {warning}", file=out)
    for name in PLOTS:
        print(f"wrote {render_plot(store, case_id, name, ds)}", file=out)
    return 0


def _open_stored(store: ResultStore, case_id: str, results: str, out: TextIO) -> xr.Dataset | None:
    """The stored result of ``case_id`` (None, with the failure printed, if the case failed)."""
    if not store.is_stored(case_id):
        error = store.read_error(case_id)
        if error is None:
            raise InputError(f"case {case_id} is not in {results}")
        print(f"case {case_id} failed: {error['error']}", file=out)
        return None
    try:
        return store.open_case(case_id)
    except Exception as exc:  # truncated or corrupted: say so, and how to get it back
        raise InputError(f"the stored result of case {case_id} cannot be read ({type(exc).__name__}: {exc}); "
                         "tunnel-contact run (or sweep) with its case recomputes it") from None


def report_command(case_id: str, results: str, *, output: str | None = None, out: TextIO | None = None,
                   title: dict | None = None) -> int:
    """Write the PDF report of a stored case (``case_id`` may be a unique prefix) to ``output``
    (default ``<case_id>.pdf``), with the title block's ``title`` fields; 1 if the case failed."""
    out = out or sys.stdout
    from .artifacts import render_report

    store = ResultStore(results)
    case_id = resolve_case_id(store, case_id)
    ds = _open_stored(store, case_id, results, out)
    if ds is None:
        return 1
    target = Path(output or f"{case_id}.pdf")
    if target.is_dir():
        target = target / f"{case_id}.pdf"
    shutil.copyfile(render_report(store, case_id, ds, title=title), target)
    print(f"wrote {target} (report of case {case_id})", file=out)
    return 0
