"""Files derived from stored results, built on first request and kept under the results directory.

Layout::

    <root>/plots/<case_id>/<name>.png            a figure of one case (workflows.plots)
    <root>/sweeps/<sweep_id>-<digest>.nc         the combined result of a sweep's finished
                                                 cases; ``digest`` hashes which cases, so a
                                                 file never goes stale as more cases finish
    <root>/sweeps/plots/<sweep_id>-<digest>-<name>.png
                                                 a figure of those cases (workflows.plots)

All are written atomically (temporary file, then rename) with a checksum, so a concurrent
request either finds the complete file or builds its own copy, and a cached file damaged
since, or whose checksum is gone, is built again, never served. netCDF/HDF5 and matplotlib are
not safe to drive from several threads at once, so building is serialised by a lock.
A case's cached plots are removed whenever its result is written again
(:meth:`workflows.result_store.ResultStore.write_case`). Used by the CLI's ``show`` and by the
service. The paths come from :class:`workflows.result_store.ResultStore`; ``root`` is a store or
its folder.
"""
from __future__ import annotations

import json

import logging
import threading
import time
from pathlib import Path
from typing import Sequence

import xarray as xr

from .combine import for_netcdf
from .files import DamagedFile, remove_checksum, unverifiable, verify, write_atomically
from .plots import PLOTS, STAGED_PLOTS, SWEEP_PLOT_NAMES, SWEEP_PLOTS, case_labels, plot_interaction
from .result_store import ResultStore, StoreLike, as_store, netcdf_lock

logger = logging.getLogger(__name__)

_BUILD_LOCK = threading.Lock()
#: Seconds after which a superseded combined file is deleted.
_STALE_AFTER = 300.0


def plot_path(root: StoreLike, case_id: str, name: str) -> Path:
    """Where the PNG ``name`` of ``case_id`` is cached."""
    return as_store(root).plot_path(case_id, name)


def render_plot(root: StoreLike, case_id: str, name: str, ds=None, *, stage: str | None = None) -> Path:
    """The cached PNG of plot ``name`` of a stored case, rendered first if missing.

    ``ds`` is the case's result if the caller has it open already; ``stage`` the construction
    stage a plot of :data:`workflows.plots.STAGED_PLOTS` shows (``"total"``, ``"1"``, ``"2"``).

    Raises
    ------
    KeyError
        If ``name`` is not one of :data:`workflows.plots.PLOTS`.
    FileNotFoundError
        If the case is not stored.
    """
    plot = PLOTS[name]
    if stage is not None and name not in STAGED_PLOTS:
        raise ValueError(f"stage: the plot {name!r} has no stages (only {', '.join(STAGED_PLOTS)})")
    store = as_store(root)
    target = store.plot_path(case_id, name if stage in (None, "total") else f"{name}-stage{stage}")
    if _intact(target):
        return target
    with _BUILD_LOCK:
        if not _intact(target):
            data = store.open_case(case_id) if ds is None else ds
            figure = plot(data) if stage is None else plot(data, stage=stage)
            write_atomically(target, lambda tmp: figure.savefig(tmp, format="png", dpi=110), checksum=True)
            logger.info("rendered %s of case %s", name, case_id)
    return target


def render_report(root: StoreLike, case_id: str, ds=None, *, title: dict | None = None) -> Path:
    """The cached PDF report of a stored case (:func:`workflows.report.case_report`), written
    first if missing; kept beside the case's plots (removed with them when the case is). A
    report with a title block (``title``: :data:`workflows.report.TITLE_FIELDS`) is cached apart,
    per title."""
    from solver.spec import content_id

    from .reliability_methods.records import design_point_notes
    from .report import case_report, title_block

    store = as_store(root)
    given = {k: v for k, v in (title or {}).items() if v not in (None, "")}
    if given:
        title_block(given)  # refuse an unknown field before writing anything
    stem = "report" if not given else f"report-{content_id(json.dumps(given, sort_keys=True))}"
    target = store.plot_dir(case_id) / f"{stem}.pdf"
    if _intact(target):
        return target
    with _BUILD_LOCK:
        if not _intact(target):
            pdf = case_report(store.open_case(case_id) if ds is None else ds, title=given,
                              notes=design_point_notes(store, case_id))
            write_atomically(target, lambda tmp: Path(tmp).write_bytes(pdf), checksum=True)
            logger.info("wrote the report of case %s", case_id)
    return target


def combined_path(root: StoreLike, sweep_id: str, case_ids: Sequence[str]) -> Path:
    """Where the combined file of ``sweep_id`` over exactly ``case_ids`` is kept."""
    return as_store(root).combined_path(sweep_id, case_ids)


def write_combined(root: StoreLike, sweep_id: str, case_ids: Sequence[str]) -> Path:
    """The combined netCDF of ``case_ids`` (stored cases, in sweep order), written if missing.

    Older combined files of the same sweep (fewer finished cases) are removed once
    they are a few minutes old, so no response still streaming one loses it.
    """
    store = as_store(root)
    target = store.combined_path(sweep_id, case_ids)
    if _intact(target) or store.url and store.fetched(target) and _intact(target):
        return target
    with _BUILD_LOCK:
        if not _intact(target):
            combined = store.open_results(list(case_ids))
            with netcdf_lock:
                write_atomically(target, lambda tmp: for_netcdf(combined).to_netcdf(tmp, engine="netcdf4"),
                                 checksum=True)
            store.publish(target)  # on object storage: one object, its checksum beside it
            logger.info("combined %d cases of sweep %s into %s", len(case_ids), sweep_id, target.name)
            _remove_superseded(target, f"{sweep_id}-*.nc")
    return target


def _remove_superseded(target: Path, pattern: str) -> None:
    """Delete the files beside ``target`` matching ``pattern`` (and their checksums) that are
    older than :data:`_STALE_AFTER`: copies over fewer cases of the same sweep."""
    for old in target.parent.glob(pattern):
        try:
            stale = old != target and time.time() - old.stat().st_mtime > _STALE_AFTER
        except FileNotFoundError:  # removed by a concurrent request
            continue
        if stale:
            old.unlink(missing_ok=True)
            remove_checksum(old)


def _intact(path: Path) -> bool:
    """True when ``path`` is there and matches its checksum (a damaged copy, or one whose
    checksum is gone, is built again)."""
    try:
        verify(path, without_checksum=unverifiable)
    except FileNotFoundError:
        return False
    except DamagedFile as exc:
        logger.warning("%s; building it again", exc)
        return False
    return True


def render_sweep_plot(root: StoreLike, sweep_id: str, case_ids: Sequence[str], name: str) -> Path:
    """The cached PNG of sweep plot ``name`` over ``case_ids`` (stored cases), rendered if missing.

    ``name`` is one of :data:`workflows.plots.SWEEP_PLOT_NAMES`; ``interaction`` reads
    every case's file (their design envelopes are not part of the combined results) and
    adds ``max_utilization`` against each varied parameter.
    Figures over fewer cases of the same sweep are removed once a few minutes old.

    Raises
    ------
    KeyError
        If ``name`` is not a sweep plot.
    """
    if name not in SWEEP_PLOT_NAMES:
        raise KeyError(name)
    store = as_store(root)
    target = store.sweep_plot_path(sweep_id, case_ids, name)
    if _intact(target):
        return target
    with _BUILD_LOCK:
        if not _intact(target):
            combined = store.open_results(list(case_ids))
            if name == "interaction":
                figure = plot_interaction([_section_forces(store, c) for c in case_ids], case_labels(combined),
                                          combined=combined)
            else:
                figure = SWEEP_PLOTS[name](combined)
            write_atomically(target, lambda tmp: figure.savefig(tmp, format="png", dpi=90), checksum=True)
            logger.info("rendered %s of sweep %s (%d cases)", name, sweep_id, len(case_ids))
            _remove_superseded(target, f"{sweep_id}-*-{name}.png")
    return target


def _section_forces(store: ResultStore, case_id: str) -> xr.Dataset:
    """The lining forces and design envelope of a stored case, without its mesh and fields."""
    with store.opened(case_id) as ds:
        names = [v for v in ("thrust", "moment", "utilization", "capacity_thrust", "capacity_moment") if v in ds]
        return ds[names].load()
