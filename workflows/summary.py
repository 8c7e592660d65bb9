"""Small summaries of results: the 0-d scalars of a case as plain floats."""
from __future__ import annotations

import xarray as xr

from .store_files import FilesLike, data_variables, files_of


def summarize(ds: xr.Dataset) -> dict[str, float]:
    """``{name: value}`` of every 0-d data variable of a result (SPEC §3 scalars)."""
    return {name: float(var.values) for name, var in data_variables(ds)
            if var.ndim == 0 and var.dtype.kind in "biuf" and name != "mesh"}


def read_summary(root: FilesLike, case_id: str) -> dict[str, float]:
    """Summary of a stored case, reading only its scalars (older spelling of
    :meth:`workflows.result_store.ResultStore.read_summary`)."""
    with files_of(root).opened(case_id) as ds:
        return summarize(ds)
