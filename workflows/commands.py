"""What the ``tunnel-contact`` commands do (``service/cli.py`` only parses arguments).

Each command writes its human-readable report to ``out`` and returns an exit code.
Bad input (unreadable or invalid JSON, a malformed or unknown case id) raises
:class:`InputError` with a one-line message; the CLI prints it and exits with 2.
"""
from __future__ import annotations

import json
import logging
import math
import os
import shutil
import sys
from collections.abc import Iterable
from pathlib import Path
from typing import Any, TextIO

import numpy as np
import xarray as xr
from pydantic import ValidationError

from solver import CaseSpec, SolverError
from solver.results.dataset import SCALARS
from solver.errors import field_errors, format_errors
from solver.spec import is_number

from .joint_check import joint_report
from .section_check import section_report
from .joint_plots import has_joints
from .parameters import flat_parameters, parameter_attrs, parameter_path, varying_parameters
from .result_store import ResultStore, StoreLike, as_store, case_warnings, check_case_id
from .summary import summarize
from .sweep import Sweep, SweepError, run_sweep
from .units import DIAGNOSTICS, display_unit, parameter_unit, shown_number, shown_value


#: Columns of the comparison table: (summary scalar, header); values and units as every table
#: shows them (:mod:`workflows.units`).
TABLE_COLUMNS: tuple[tuple[str, str], ...] = (
    ("max_contact_pressure", "max λ"),
    ("contact_extent", "contact"),
    ("max_thrust", "max N"),
    ("max_abs_moment", "max |M|"),
    ("max_utilization", "max η"),
    ("crown_settlement", "lining crown"),
    ("ground_crown_settlement", "ground crown"),
    ("ground_loss", "ground loss"),
    ("gaussian_max_settlement", "trough max"),
    ("axis_settlement", "FE surface"),
)

#: Columns added to the comparison table when a case has a segmental lining (SPEC §1.6).
JOINT_TABLE_COLUMNS: tuple[tuple[str, str], ...] = (
    ("max_joint_opening", "joint gap"),
    ("max_joint_rotation", "joint rot."),
    ("max_joint_eccentricity", "joint |M|/(Na/2)"),
    ("max_joint_utilization", "joint η"),
)


def column_unit(name: str) -> str:
    """The unit row's label of result column ``name`` (the utilization and the joints'
    eccentricity: their limit, ``≤ 1``)."""
    if name in ("max_utilization", "max_joint_eccentricity", "max_joint_utilization"):
        return "≤ 1"
    return display_unit(SCALARS[name][0], name)[0]


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
    name = ds.attrs.get("case_name")
    print(f"case {case_id}" + (f" ({name})" if name else ""), file=out)
    print("\n".join(f"  {k} = {_input_text(k, v)}" for k, v in params.items()), file=out)
    print(format_summary(summarize(ds)), file=out)
    if "utilization" in ds:
        print(utilization_report(ds), file=out)
        print(section_report(ds), file=out)
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


def report_command(case_id: str, results: str, *, output: str | None = None, out: TextIO | None = None) -> int:
    """Write the PDF report of a stored case (``case_id`` may be a unique prefix) to ``output``
    (default ``<case_id>.pdf``); 1 if the case failed."""
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
    shutil.copyfile(render_report(store, case_id, ds), target)
    print(f"wrote {target} (report of case {case_id})", file=out)
    return 0


def format_summary(summary: dict[str, float]) -> str:
    """The scalars of one case, one ``name = value unit`` per line, in the engineering units
    of every table and page (:mod:`workflows.units`: kPa, kN/m, kN·m/m, mm, %), the
    solver's diagnostics after a ``solver:`` line; non-finite values as ``inf``/``-``.
    """
    width = max((len(k) for k in summary), default=0)

    def line(k: str) -> str:
        return f"  {k:<{width}} = {shown_value(summary[k], SCALARS.get(k, (None,))[0], k, 6)}"

    return "\n".join([line(k) for k in summary if k not in DIAGNOSTICS] + ["  solver:"]
                     + [line(k) for k in summary if k in DIAGNOSTICS])


def _input_text(name: str, value: Any) -> str:
    """An input as people read it: in its engineering unit (:func:`workflows.units.parameter_unit`)."""
    units = parameter_attrs(name, numeric=is_number(value)).get("units")
    if not units:
        return str(value)
    unit, factor = parameter_unit(parameter_path(name), units)
    return f"{value * factor:.6g} {unit}" if unit not in ("", "1") else f"{value:.6g}"


def utilization_report(ds: xr.Dataset) -> str:
    """Where the lining is most utilized (EN 1992-1-1, SPEC §1.3): η, θ, side, N_Ed and M_Ed there
    (a segmental lining's section away from its joints: :func:`workflows.joint_check.joint_report`
    states the joints)."""
    from .case_plots import load_factor, station_name

    eta = ds["utilization"].values
    if np.isnan(eta).all():
        return "max utilization: not computed"
    k = int(np.nanargmax(eta))
    gamma = load_factor(ds)
    theta = float(ds["theta"].values[k])
    # N_Ed of the governing combination: γF N, or 1.0 N where a lower thrust is unfavourable (SPEC §9.3)
    thrust = ds["design_thrust"] if "design_thrust" in ds else gamma * ds["thrust"]
    n_ed, m_ed = float(thrust.values[k]), gamma * float(ds["moment"].values[k])
    worst = float(eta[k])
    verdict = "passes" if worst <= 1 else "fails" + (" at any load level" if math.isinf(worst) else "")
    fibre = "inner fibre compressed" if m_ed > 0 else "outer fibre compressed"
    failing = int(np.count_nonzero(eta > 1))
    checked = int(np.count_nonzero(~np.isnan(eta)))  # a segmental lining's joints are their strips'
    where = " away from the joints" if has_joints(ds) else ""
    combination = "" if abs(n_ed - gamma * float(ds["thrust"].values[k])) <= 1e-9 * abs(n_ed) else \
        " (1.0 N: the lower thrust governs)"
    return (f"max utilization η = {worst:.3g}{where} ({verdict}; EN 1992-1-1, γF = {gamma:g} on M, "
            f"the worse of γF N and 1.0 N)\n"
            f"  at θ = {theta:.1f}° ({station_name(theta)} side): N_Ed = {n_ed / 1e3:.1f} kN/m, "
            f"M_Ed = {m_ed / 1e3:.1f} kN·m/m ({fibre}){combination}\n"
            f"  stations with η > 1: {failing} of {checked}")


def case_row(results: StoreLike, case_id: str) -> dict[str, Any]:
    """``{"case_id", "status", "params", "summary", "error"}`` of a case in the store."""
    store = as_store(results)
    if store.is_stored(case_id):
        with store.opened(case_id) as ds:
            return {"case_id": case_id, "status": "done", "error": None,
                    "params": flat_parameters(ds.attrs["case_spec"]), "summary": summarize(ds)}
    error = store.read_error(case_id) or {}
    return {"case_id": case_id, "status": "failed" if error else "missing",
            "params": flat_parameters(error["spec"]) if "spec" in error else {},
            "summary": {}, "error": error.get("error")}


def case_rows(results: StoreLike, case_ids: list[str]) -> list[dict[str, Any]]:
    """:func:`case_row` of each case; the stored ones come from the index in one read."""
    store = as_store(results)
    stored = store.file_keys()  # one directory scan, not a stat per case
    done = [c for c in case_ids if c in stored]
    rows: dict[str, dict[str, Any]] = {}
    try:
        combined = store.open_results(done) if done else None
    except FileNotFoundError:  # a case removed meanwhile: one by one
        combined = None
    if combined is not None:
        scalars = [str(n) for n, v in combined.data_vars.items() if v.dims == ("case",) and v.dtype.kind in "biuf"]
        for i, case_id in enumerate(done):
            rows[case_id] = {"case_id": case_id, "status": "done", "error": None,
                             "params": flat_parameters(str(combined["case_spec"].values[i])),
                             "summary": {n: float(combined[n].values[i]) for n in scalars}}
    return [rows[c] if c in rows else case_row(store, c) for c in case_ids]


def comparison_table(rows: Iterable[dict[str, Any]]) -> str:
    """Plain-text table: case id, the parameters that vary, the key results (two header lines:
    names, then units); the joints' maxima too when a case has a segmental lining.

    ``rows`` are :func:`case_row` dicts; failed cases show their status instead of numbers;
    a missing or NaN value shows ``-``, an infinite one ``inf``.
    """
    rows = list(rows)
    varied = varying_parameters([r["params"] for r in rows if r["params"]])
    columns = TABLE_COLUMNS
    if any(r["params"].get("lining_joints_count", 0) for r in rows):  # a segmental lining among them
        columns += JOINT_TABLE_COLUMNS
    header = ["case_id", *varied, *(h for _, h in columns)]
    shown = [_parameter_shown(n) for n in varied]  # engineering units, as every table shows inputs
    units = ["", *(u for u, _ in shown), *(column_unit(k) for k, _ in columns)]
    lines = []
    for r in rows:
        cells = [r["case_id"], *(_fmt(_scaled(r["params"].get(n, ""), f)) for n, (_, f) in zip(varied, shown))]
        if r["status"] == "done":
            cells += [shown_number(r["summary"].get(k), SCALARS[k][0], k) for k, _ in columns]
        else:
            cells += [r["status"]] + [""] * (len(columns) - 1)
        lines.append(cells)
    widths = [max(len(str(c)) for c in col) for col in zip(header, units, *lines)]
    fmt = "  ".join(f"{{:>{w}}}" for w in widths)
    text = [fmt.format(*header), fmt.format(*units).rstrip(), fmt.format(*("-" * w for w in widths))]
    text += [fmt.format(*cells) for cells in lines]
    errors = [f"  {r['case_id']}: {r['error']}" for r in rows if r["error"]]
    return "\n".join(text + (["failures:"] + errors if errors else []))


def _parameter_shown(name: str) -> tuple[str, float]:
    units = parameter_attrs(name).get("units")
    unit, factor = parameter_unit(parameter_path(name), units) if units else ("", 1.0)
    return ("" if unit == "1" else unit), factor


def _scaled(value: Any, factor: float) -> Any:
    return value * factor if is_number(value) else value


def _fmt(value: Any) -> str:
    return f"{value:.4g}" if isinstance(value, float) else str(value)
