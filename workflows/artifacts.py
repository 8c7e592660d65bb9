"""Files derived from stored results, built on first request and kept under the results directory.

Layout::

    <root>/plots/<case_id>/<name>.png            a figure of one case (workflows.plots)
    <root>/sweeps/<sweep_id>-<digest>.nc         the combined result of a sweep's finished
                                                 cases; ``digest`` hashes which cases, so a
                                                 file never goes stale as more cases finish

Both are written atomically (temporary file, then rename), so a concurrent request
either finds the complete file or builds its own copy. netCDF/HDF5 and matplotlib are
not safe to drive from several threads at once, so building is serialised by a lock.
A case's cached plots are removed whenever its result is written again
(:func:`workflows.store.write_case`). Used by the CLI's ``show`` and by the service.
"""
from __future__ import annotations

import hashlib
import logging
import threading
import time
from pathlib import Path
from typing import Sequence

from .combine import open_results
from .plots import PLOTS
from .store import open_case, plot_dir, write_atomically

logger = logging.getLogger(__name__)

_BUILD_LOCK = threading.Lock()
#: Seconds after which a superseded combined file is deleted.
_STALE_AFTER = 300.0


def plot_path(root: Path, case_id: str, name: str) -> Path:
    """Where the PNG ``name`` of ``case_id`` is cached."""
    return plot_dir(root, case_id) / f"{name}.png"


def render_plot(root: Path, case_id: str, name: str, ds=None) -> Path:
    """The cached PNG of plot ``name`` of a stored case, rendered first if missing.

    ``ds`` is the case's result if the caller has it open already.

    Raises
    ------
    KeyError
        If ``name`` is not one of :data:`workflows.plots.PLOTS`.
    FileNotFoundError
        If the case is not stored.
    """
    plot = PLOTS[name]
    target = plot_path(root, case_id, name)
    if target.is_file():
        return target
    with _BUILD_LOCK:
        if not target.is_file():
            figure = plot(open_case(root, case_id) if ds is None else ds)
            write_atomically(target, lambda tmp: figure.savefig(tmp, format="png", dpi=110))
            logger.info("rendered %s of case %s", name, case_id)
    return target


def combined_path(root: Path, sweep_id: str, case_ids: Sequence[str]) -> Path:
    """Where the combined file of ``sweep_id`` over exactly ``case_ids`` is kept."""
    digest = hashlib.sha256(",".join(case_ids).encode()).hexdigest()[:12]
    return Path(root) / "sweeps" / f"{sweep_id}-{digest}.nc"


def write_combined(root: Path, sweep_id: str, case_ids: Sequence[str]) -> Path:
    """The combined netCDF of ``case_ids`` (stored cases, in sweep order), written if missing.

    Older combined files of the same sweep (fewer finished cases) are removed once
    they are a few minutes old, so no response still streaming one loses it.
    """
    target = combined_path(root, sweep_id, case_ids)
    if target.is_file():
        return target
    with _BUILD_LOCK:
        if not target.is_file():
            combined = open_results(root, case_ids=list(case_ids))
            write_atomically(target, lambda tmp: combined.to_netcdf(tmp, engine="netcdf4"))
            logger.info("combined %d cases of sweep %s into %s", len(case_ids), sweep_id, target.name)
            for old in target.parent.glob(f"{sweep_id}-*.nc"):
                if old != target and time.time() - old.stat().st_mtime > _STALE_AFTER:
                    old.unlink(missing_ok=True)
    return target
