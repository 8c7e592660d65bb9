"""The result store: one netCDF-4 file per case under ``<root>/cases/``.

Layout::

    <root>/cases/<case_id>.nc          the result Dataset (SPEC §3)
    <root>/cases/<case_id>.error.json  why the case could not be solved

Both are written atomically (temporary file in the same folder, flush, fsync,
``os.replace``), so a reader never sees a half-written file under a final name and
a crash leaves at most a ``.tmp`` file that :func:`remove_stale_temporaries` cleans.
This is the only module that writes case files.
"""
from __future__ import annotations

import json
import logging
import os
import re
import shutil
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import dask
import xarray as xr

import solver
from solver.spec import CaseSpec

logger = logging.getLogger(__name__)

_CASE_ID = re.compile(r"[0-9a-f]{16}")
_TMP_SUFFIX = ".tmp"
#: Options every case file is opened with: values come back exactly as written
#: (integer ``face_nodes`` keep their dtype and ``_FillValue`` attribute).
OPEN_OPTIONS: dict[str, Any] = dict(
    engine="netcdf4", mask_and_scale=False, decode_times=False, decode_timedelta=False)


def check_case_id(case_id: str) -> str:
    """Return ``case_id`` if it is 16 lowercase hex digits, else raise ``ValueError``.

    Every id is checked before it becomes part of a path.
    """
    if not isinstance(case_id, str) or not _CASE_ID.fullmatch(case_id):
        raise ValueError(f"case id {case_id!r} is not 16 lowercase hex digits")
    return case_id


def cases_dir(root: str | os.PathLike) -> Path:
    """Folder holding the case files of the store at ``root``."""
    return Path(root) / "cases"


def case_path(root: str | os.PathLike, case_id: str) -> Path:
    """Path of the result file of ``case_id`` (it may not exist)."""
    return cases_dir(root) / f"{check_case_id(case_id)}.nc"


def error_path(root: str | os.PathLike, case_id: str) -> Path:
    """Path of the error record of ``case_id`` (it may not exist)."""
    return cases_dir(root) / f"{check_case_id(case_id)}.error.json"


def plot_dir(root: str | os.PathLike, case_id: str) -> Path:
    """Folder of the cached figures of ``case_id`` (see :mod:`workflows.artifacts`)."""
    return Path(root) / "plots" / check_case_id(case_id)


def is_stored(root: str | os.PathLike, case_id: str) -> bool:
    """True when the result of ``case_id`` is in the store."""
    return case_path(root, case_id).is_file()


def stored_case_ids(root: str | os.PathLike) -> list[str]:
    """Ids of all stored results, sorted."""
    folder = cases_dir(root)
    if not folder.is_dir():
        return []
    return sorted(p.stem for p in folder.glob("*.nc") if _CASE_ID.fullmatch(p.stem))


def run_and_store(spec: CaseSpec | dict[str, Any], root: str | os.PathLike, *, force: bool = False) -> str:
    """Solve ``spec`` and store its result; return the case id.

    A case already stored is returned without computing unless ``force``. When the
    solver raises, the error is recorded with :func:`write_error` and re-raised; a
    later success removes that record.

    Parameters
    ----------
    spec : the case (a :class:`CaseSpec` or its dict).
    root : folder of the store (created if missing).
    force : recompute even if the result exists.
    """
    spec = CaseSpec.model_validate(spec)
    case_id = spec.case_id
    if not force and is_stored(root, case_id):
        logger.info("case %s already stored, not recomputed", case_id)
        return case_id
    logger.info("solving case %s", case_id)
    try:
        ds = solver.run_case(spec)
    except Exception as exc:
        write_error(root, spec, exc)
        raise
    write_case(root, ds)
    return case_id


def write_case(root: str | os.PathLike, ds: xr.Dataset) -> Path:
    """Write a result Dataset atomically under its ``case_id`` attribute; return the path."""
    case_id = check_case_id(ds.attrs.get("case_id"))
    target = case_path(root, case_id)

    def write(tmp: Path) -> None:
        # in-memory data to a private file: no dask, and no cluster-wide write lock
        # (xarray would take a distributed.Lock when called inside a dask worker)
        with dask.config.set(scheduler="synchronous"):
            ds.to_netcdf(tmp, engine="netcdf4", format="NETCDF4", encoding=_encoding(ds))

    write_atomically(target, write)
    error_path(root, case_id).unlink(missing_ok=True)
    shutil.rmtree(plot_dir(root, case_id), ignore_errors=True)  # figures of an older result
    logger.info("stored case %s in %s", case_id, target)
    return target


def _encoding(ds: xr.Dataset) -> dict[str, dict[str, Any]]:
    """netCDF encoding: no ``_FillValue`` where the data set has none, compressed arrays.

    xarray would otherwise add ``_FillValue = NaN`` to every float variable, which is
    a pure encoding artefact and would break the exact round trip.
    """
    enc: dict[str, dict[str, Any]] = {}
    for name, var in ds.variables.items():
        e: dict[str, Any] = {}
        if "_FillValue" not in var.attrs and "_FillValue" not in var.encoding:
            e["_FillValue"] = None
        if var.ndim and var.size > 1000 and var.dtype.kind in "iuf":
            e.update(zlib=True, complevel=4)
        enc[str(name)] = e
    return enc


def open_case(root: str | os.PathLike, case_id: str) -> xr.Dataset:
    """Read the stored result of ``case_id`` fully into memory (the file is closed).

    Raises
    ------
    FileNotFoundError
        If the case is not stored.
    """
    path = case_path(root, case_id)
    with xr.open_dataset(path, **OPEN_OPTIONS) as ds:
        return ds.load()


def write_error(root: str | os.PathLike, spec: CaseSpec, exc: BaseException) -> Path:
    """Record why ``spec`` failed, atomically, as ``<case_id>.error.json``."""
    record = {
        "case_id": spec.case_id,
        "error": f"{type(exc).__name__}: {exc}",
        "type": type(exc).__name__,
        "time": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "spec": json.loads(spec.canonical_json()),
    }
    target = error_path(root, spec.case_id)

    def write(tmp: Path) -> None:
        tmp.write_text(json.dumps(record, indent=1, sort_keys=True))

    write_atomically(target, write)
    logger.warning("case %s failed: %s", spec.case_id, record["error"])
    return target


def read_error(root: str | os.PathLike, case_id: str) -> dict[str, Any] | None:
    """The error record of ``case_id``, or None if it has none."""
    try:
        return json.loads(error_path(root, case_id).read_text())
    except FileNotFoundError:
        return None


def remove_stale_temporaries(root: str | os.PathLike, *, older_than: float = 3600.0) -> int:
    """Delete temporary files left by killed writers (older than ``older_than`` s); return how many.

    Writers that fail normally remove their own temporary file; this is for
    processes that died mid-write (e.g. a killed worker).
    """
    folder = cases_dir(root)
    removed = 0
    for tmp in folder.glob(f"*{_TMP_SUFFIX}") if folder.is_dir() else ():
        if time.time() - tmp.stat().st_mtime > older_than:
            tmp.unlink(missing_ok=True)
            removed += 1
    return removed


def write_atomically(target: Path, write: Callable[[Path], object]) -> None:
    """Call ``write(tmp)`` on a temporary file next to ``target``, then rename it into place.

    The temporary file is flushed and fsynced before ``os.replace``; if ``write``
    raises, it is removed and nothing appears under ``target``.
    """
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=_TMP_SUFFIX, dir=target.parent)
    os.close(fd)
    tmp = Path(name)
    try:
        write(tmp)
        with open(tmp, "rb+") as fh:  # the writer closed it; make its bytes durable
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o644)
        os.replace(tmp, target)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    _fsync_dir(target.parent)


def _fsync_dir(folder: Path) -> None:
    """Make the rename durable (best effort: not every file system allows it)."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)
