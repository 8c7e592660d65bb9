"""The result store: :class:`ResultStore`, the one object that knows the file layout.

Its files (layout, reading, checksums) are :class:`workflows.store_files.StoreFiles`, which
it extends with what stands on them: the index of stored results (:mod:`workflows.index`),
combined results, and solving a case into the store. Dependence runs in one line:
``store_files -> summary -> combine -> index -> result_store``.

Every file is written atomically by :func:`workflows.files.write_atomically` (see
:mod:`workflows.store_files` for the layout). This module is the only one that writes case files.
"""
from __future__ import annotations

import errno
import json
import logging
import os
import shutil
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Union

import dask
import xarray as xr

import solver
from solver.limits import CaseCancelled
from solver.model import shared_model
from solver.spec import CaseSpec

from .files import remove_checksum, remove_stale_temporaries, write_atomically
from .index import ResultIndex
from .netcdf_write import write_netcdf
from .object_store import object_key
from .store_files import (CONTENT_DIGEST, OPEN_OPTIONS, RESULT_BYTES_PER_ELEMENT, RESULT_MARGIN, STORE_FULL,
                          FileKey, StoreFiles, StoreFull, case_warnings, check_case_id, content_digest,
                          estimated_result_bytes, file_key, free_bytes, netcdf_encoding, netcdf_lock)
from .summary import summarize

__all__ = ["OPEN_OPTIONS", "RESULT_BYTES_PER_ELEMENT", "RESULT_MARGIN", "STORE_FULL", "FileKey", "ResultStore",
           "StoreFiles", "StoreFull", "StoreLike", "as_store", "case_warnings", "check_case_id",
           "estimated_result_bytes", "file_key", "free_bytes", "netcdf_encoding", "netcdf_lock", "open_case",
           "open_results", "run_and_store"]

logger = logging.getLogger(__name__)


class ResultStore(StoreFiles):
    """The results directory ``root`` and everything stored under it: its files
    (:class:`~workflows.store_files.StoreFiles`), their index, and the solving of cases into it.

    Cheap to create and picklable (it holds only the path), so it can be handed to
    dask tasks; all state is in the files.
    """

    # -- reading through the index -----------------------------------------------------

    def read_summary(self, case_id: str) -> dict[str, float]:
        """The scalars of a stored case (see :func:`workflows.summary.summarize`), reading only them."""
        with self.opened(case_id) as ds:
            return summarize(ds)

    def unreadable(self, case_ids: Sequence[str]) -> list[str]:
        """The stored cases of ``case_ids`` whose file cannot be read (truncated, corrupted):
        to recompute, never to serve. Files the index vouches for are not opened; the rest
        are read once."""
        return [c for c in self.index.unverified(case_ids) if self._readable_outcome(c) is None]

    def read_outcome(self, case_id: str) -> tuple[dict[str, float], list[str]]:
        """The scalars and the warnings (:func:`case_warnings`) of a stored case, one read."""
        with self.opened(case_id) as ds:
            return summarize(ds), case_warnings(ds)

    def _readable_outcome(self, case_id: str) -> tuple[dict[str, float], list[str]] | None:
        """:meth:`read_outcome`, or None when the file is gone or cannot be read (a truncated
        or corrupted file is logged: it is to be recomputed, never served)."""
        try:
            return self.read_outcome(case_id)
        except FileNotFoundError:
            return None
        except Exception as exc:
            logger.warning("stored result of case %s is unreadable (%s: %s); recomputing it",
                           case_id, type(exc).__name__, exc)
            return None

    @property
    def index(self) -> ResultIndex:
        """The index of stored results (scalars and θ-grid interface quantities)."""
        return ResultIndex(self)

    def open_results(self, case_ids: Sequence[str] | None = None) -> xr.Dataset:
        """Stored cases combined along ``case``; see :func:`workflows.open_results`."""
        return self.index.open_results(case_ids)

    # -- writing -----------------------------------------------------------------------

    def run_and_store(self, spec: CaseSpec | dict[str, Any], *, force: bool = False) -> str:
        """Solve ``spec`` and store its result; return the case id.

        A case already stored is returned without computing unless ``force``. When the
        solver raises, the error is recorded with :meth:`write_error` and re-raised; a
        later success removes that record.
        """
        spec = CaseSpec.model_validate(spec)
        if not force and self.is_stored(spec.case_id):
            logger.info("case %s already stored, not recomputed", spec.case_id)
        else:
            self._solve(spec)
        return spec.case_id

    def solve_or_read(self, spec: CaseSpec, *, force: bool = False
                      ) -> tuple[dict[str, float], list[str], bool]:
        """The scalars and warnings (:func:`case_warnings`) of ``spec``'s result and whether
        they were computed now: read from the stored file unless ``force``, computed (and
        stored) when there is none or it cannot be read."""
        if not force and self.is_stored(spec.case_id):
            outcome = self._readable_outcome(spec.case_id)
            if outcome is not None:
                return (*outcome, False)
        return (*self._solve(spec), True)

    def _solve(self, spec: CaseSpec) -> tuple[dict[str, float], list[str]]:
        """Solve and store ``spec``; its scalars and warnings, from memory. A solver failure
        is recorded (:meth:`write_error`) and re-raised."""
        logger.info("solving case %s", spec.case_id)
        # a cancel request older than this solve (its case ended first) is void: in a folder removed
        # now; in a bucket found stale by its age when the solve first asks (no request a case)
        started = time.monotonic()
        if not self.url:
            self.clear_cancel(spec.case_id)
        stored = False
        try:
            self.check_room(spec)  # before the work, not after it
            # cases sharing geometry, mesh and materials reuse one factorized model per process
            ds = solver.run_case(spec, model=shared_model(spec), stop=lambda: self.cancel_requested(
                spec.case_id, running_for=time.monotonic() - started))
            try:
                self.write_case(ds)
                stored = True
            except Exception as exc:
                full = self._full_or(exc, spec)
                if full is exc:
                    raise
                raise full from exc
        except CaseCancelled:
            raise  # given up, not failed: no error record
        except Exception as exc:
            try:
                self.write_error(spec, exc)
            except OSError:  # a store too full for the record too: the caller still has the error
                logger.warning("could not record the failure of case %s", spec.case_id)
            raise
        finally:
            if not (stored and self.url):  # a stored object's cancel request went with its error record
                self.clear_cancel(spec.case_id)
        return summarize(ds), case_warnings(ds)

    def check_room(self, spec: CaseSpec) -> None:
        """Raise :class:`StoreFull` when the store lacks the room the result of ``spec`` needs."""
        need, free = estimated_result_bytes(spec), free_bytes(self.root)
        if free < need:
            raise self._full(free, need)

    def _full(self, free: int, need: int) -> StoreFull:
        return StoreFull(f"the results store is full: {free / 2**20:.1f} MiB free where this case needs "
                         f"about {need / 2**20:.0f} MiB; free some space (or enlarge the store) and the "
                         "service computes it again by itself, or submit it again with ?retry=failed")

    def _full_or(self, exc: Exception, spec: CaseSpec) -> Exception:
        """``exc`` of a failed write as :class:`StoreFull` when the store ran out of room
        (netCDF reports a full disk as "NetCDF: HDF error"), else ``exc`` itself."""
        need, free = estimated_result_bytes(spec), free_bytes(self.root)
        full = isinstance(exc, OSError) and exc.errno in (errno.ENOSPC, errno.EDQUOT)
        return self._full(free, need) if full or free < need else exc

    def write_case(self, ds: xr.Dataset) -> Path:
        """Write a result Dataset atomically under its ``case_id`` attribute; return the path.

        Also drops the case's error record and cached figures (they belong to an older
        result) and writes its index entry.
        """
        case_id = check_case_id(ds.attrs.get("case_id"))
        target = self.case_path(case_id)
        stored = ds.assign_attrs({CONTENT_DIGEST: content_digest(ds)})  # verifiable without its .b2

        def write(tmp: Path) -> None:
            # in-memory data to a private file: no dask, and no cluster-wide write lock
            # (xarray would take a distributed.Lock when called inside a dask worker)
            with dask.config.set(scheduler="synchronous"):
                with netcdf_lock:
                    write_netcdf(stored, tmp, netcdf_encoding(ds))

        # on object storage the object is the durable copy: the cached one is not fsynced (a damaged
        # copy is fetched again, :meth:`verified_copy`)
        write_atomically(target, write, checksum=True, durable=not self.url)
        key = file_key(target.stat())
        if self.url:  # the object, checksum first; its key is the object's version
            key = object_key(self.remote.publish(target, checksum_in_metadata=True))  # read by fetch's HEAD
            # an older failure's record and a cancel request, void now: one bulk request
            self.remote.remove(self.error_path(case_id), self.cancel_marker(case_id))
        self.error_path(case_id).unlink(missing_ok=True)
        shutil.rmtree(self.plot_dir(case_id), ignore_errors=True)  # figures of an older result
        self.index.add(ds, key)
        logger.info("stored case %s in %s", case_id, target)
        return target

    def write_error(self, spec: CaseSpec, exc: BaseException) -> Path:
        """Record why ``spec`` failed, atomically, as ``<case_id>.error.json``."""
        record = {
            "case_id": spec.case_id,
            "error": f"{type(exc).__name__}: {exc}",
            "type": type(exc).__name__,
            "time": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
            "spec": json.loads(spec.canonical_json()),
        }
        target = self.error_path(spec.case_id)
        write_atomically(target, lambda tmp: tmp.write_text(json.dumps(record, indent=1, sort_keys=True)))
        self.publish(target)
        logger.warning("case %s failed: %s", spec.case_id, record["error"])
        return target

    def remove_case(self, case_id: str) -> None:
        """Delete a case's result, error record, figures and index entry (nothing if absent)."""
        self.case_path(case_id).unlink(missing_ok=True)
        remove_checksum(self.case_path(case_id))
        self.error_path(case_id).unlink(missing_ok=True)
        shutil.rmtree(self.plot_dir(case_id), ignore_errors=True)
        self.index.discard(case_id)
        if self.url:
            path = self.case_path(case_id)
            self.remote.remove(path.with_name(path.name + ".b2"), path, self.error_path(case_id))

    def remove_stale_temporaries(self) -> int:
        """Delete the temporary files of writers that died mid-write, in every folder of the
        store; return how many. A temporary whose writer still holds its lock stays, however
        old it looks (:func:`workflows.files.remove_stale_temporaries`)."""
        return remove_stale_temporaries(self.root)


StoreLike = Union[ResultStore, str, os.PathLike]


def as_store(root: StoreLike) -> ResultStore:
    """``root`` itself if it is a :class:`ResultStore`, else the store at that path (or of those files)."""
    if isinstance(root, ResultStore):
        return root
    return ResultStore(root)


# -- conveniences of the package (``workflows.run_and_store``, ``workflows.open_case``) -------

def run_and_store(spec: CaseSpec | dict[str, Any], root: StoreLike, *, force: bool = False) -> str:
    """Solve ``spec`` and store its result in ``root`` (a path or a store); return the case id.

    A case already stored is returned without computing unless ``force``; see
    :meth:`ResultStore.run_and_store`.
    """
    return as_store(root).run_and_store(spec, force=force)


def open_case(root: StoreLike, case_id: str) -> xr.Dataset:
    """The stored result of ``case_id`` in ``root`` (a path or a store), in memory.

    Raises
    ------
    FileNotFoundError
        If the case is not stored.
    """
    return as_store(root).open_case(case_id)


def open_results(root: StoreLike, case_ids: Sequence[str] | None = None) -> xr.Dataset:
    """Stack stored cases into one Dataset with dimension ``case``.

    Answers from the store's index (:mod:`workflows.index`), which is brought up to
    date with the case files first; the result is identical to :func:`combine_files`.

    Parameters
    ----------
    root : the result store, or the path of its folder.
    case_ids : cases to combine, in this order (duplicates dropped); default: every
        stored case, sorted by id.

    Returns
    -------
    xr.Dataset
        Dimension ``case`` with coordinate ``case_id``; every case parameter whose
        value differs between the cases as a coordinate along ``case`` named
        ``<section>_<field>`` (``ground_young`` for ``ground.young``, ``geometry_gap``
        for ``geometry.gap``; the one exception is ``geometry.thickness``, named
        ``lining_thickness``, see :mod:`workflows.parameters`); every interface
        quantity of the cases (:func:`interface_quantities`: e.g. ``contact_pressure``,
        ``thrust``, ``moment`` interpolated linearly, ``in_contact`` from the nearest
        station; a segmental lining's ``utilization`` NaN at its joints) on ``(case, theta)``
        with ``theta`` = 0, 1, ..., 180 deg; every 0-d scalar of the cases on ``case`` (the
        joints' maxima among them; the per-joint variables stay in the case files); and
        ``case_spec`` (canonical JSON) on ``case``.

    Raises
    ------
    FileNotFoundError
        If a requested case is not stored.
    ValueError
        If a case id is malformed or no case is given.
    """
    return as_store(root).open_results(case_ids)
