"""The service's view of stored result files: missing, readable or broken.

A ``done`` record promises a readable file. A file can go missing or be truncated
after the fact (a full disk, an operator, a bad copy); the service checks before it
serves one and when it reconciles, and a broken result is recomputed, never served.
A file is read once per version (modification time and size); later checks are a
``stat``.
"""
from __future__ import annotations

import logging
import math
import os
import re
from pathlib import Path
from typing import Optional

from workflows.bounded import BoundedMemo
from workflows.files import VERIFIED_MEMO, DamagedFile
from workflows.result_store import FileKey, as_store

logger = logging.getLogger(__name__)

#: Case results this process has read whole (case id -> the file version read), the most recent
#: :data:`workflows.files.VERIFIED_MEMO` (bounded: the API meets every case of its store).
_VERIFIED: BoundedMemo[str, FileKey] = BoundedMemo(VERIFIED_MEMO)


class BrokenResult(Exception):
    """A result file exists but cannot be read."""


def stored_outcome(root: Path, case_id: str) -> Optional[tuple[dict[str, float], list[str]]]:
    """Scalars and warnings of the stored result of ``case_id``; None if no file is stored.

    Raises
    ------
    BrokenResult
        If the file is there but unreadable (truncated, corrupted, not netCDF).
    """
    store = as_store(root)
    version = store.version(case_id)
    if version is None:
        return None
    try:
        outcome = store.read_outcome(case_id)  # under the process's netCDF lock
    except FileNotFoundError:
        return None
    except Exception as exc:
        raise BrokenResult(f"{type(exc).__name__}: {exc}") from None
    if version == store.version(case_id):
        _VERIFIED[case_id] = version
    return outcome


def damaged_case(exc: DamagedFile, root: Path | str) -> Optional[str]:
    """The case whose result file ``exc`` found damaged, or None if it was another file."""
    path = exc.path
    if path is None or path.parent != as_store(root).cases_dir or not path.name.endswith(".nc"):
        return None
    return path.name[:-len(".nc")]


def forget(case_id: str) -> None:
    """Read the result of ``case_id`` again at its next check (it was found damaged since)."""
    _VERIFIED.pop(case_id, None)


def written(root: Path, case_id: str) -> None:
    """Record the file a worker has just written whole (atomically, its summary taken from the
    result in memory) as read: the first GET of a new result then does not open it."""
    version = as_store(root).version(case_id)
    if version is not None:
        _VERIFIED[case_id] = version


def forget_read(case_id: str) -> None:
    """Read the file of ``case_id`` again at its next check (its copy proved unreadable)."""
    _VERIFIED.pop(case_id, None)


def result_state(root: Path, case_id: str) -> str:
    """``"missing"``, ``"readable"`` or ``"broken"`` (reads the file unless this version was read)."""
    version = as_store(root).version(case_id)
    if version is None:
        return "missing"
    if _VERIFIED.get(case_id) == version:
        return "readable"
    try:
        stored_outcome(root, case_id)
    except BrokenResult as exc:
        logger.warning("stored result of case %s is unreadable: %s", case_id, public_error(str(exc), root))
        return "broken"
    return "readable" if as_store(root).version(case_id) is not None else "missing"


def non_finite_text(value):
    """A non-finite float as the text Python's ``float()`` reads back (``inf``, ``-inf``,
    ``nan``: JSON has no such numbers); anything else as it is."""
    return repr(float(value)) if isinstance(value, float) and not math.isfinite(value) else value


def finite_summary(summary: Optional[dict]) -> Optional[dict[str, Optional[float]]]:
    """``summary`` with non-finite scalars as None (JSON has no NaN or Infinity)."""
    if summary is None:
        return None
    return {k: (float(v) if isinstance(v, (int, float)) and math.isfinite(v) else None)
            for k, v in summary.items()}


def non_finite_entries(summary: Optional[dict]) -> dict[str, str]:
    """The scalars of ``summary`` that are not finite, as ``inf``, ``-inf`` or ``nan``:
    what the nulls of :func:`finite_summary` stand for (``max_utilization`` inf: the
    section fails at any load level; ``bolt_theta`` nan: a bonded interface has none)."""
    return {k: non_finite_text(float(v)) for k, v in (summary or {}).items()
            if isinstance(v, (int, float)) and not math.isfinite(v)}


_ADDRESS = re.compile(r"\b(?:tcp|tls|ucx|ws|wss|inproc)://[\w.\-\[\]:%]*[\w\]]")
_ABSOLUTE_PATH = re.compile(r"(?<![\w.:/>])/(?:[^\s'\",;:()/]+/)+([^\s'\",;:()/]*)")


def public_error(text: str, root: Optional[Path | str] = None) -> str:
    """An error text fit for API clients: no server paths, no cluster addresses.

    The results directory becomes ``<results>``, other absolute paths their file name,
    worker and scheduler addresses ``<worker>``.

    >>> public_error("KilledWorker: last worker was tcp://10.0.0.7:40123.", "/srv/r")
    'KilledWorker: last worker was <worker>.'
    >>> public_error("OSError: [Errno 28] No space left: '/srv/r/cases/.x.nc.tmp'", "/srv/r")
    "OSError: [Errno 28] No space left: '<results>/cases/.x.nc.tmp'"
    >>> public_error("cannot open /usr/lib/x/libfoo.so", None)
    'cannot open libfoo.so'
    """
    if root is not None:
        for form in {str(root), os.path.realpath(root)}:
            text = text.replace(form.rstrip("/"), "<results>")
    text = _ADDRESS.sub("<worker>", text)
    return _ABSOLUTE_PATH.sub(lambda m: m.group(1), text)
