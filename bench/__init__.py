"""Benchmarks: each module is ``python -m bench.<name>`` and prints one run's figures."""
from __future__ import annotations

import json
import os


def one_blas_thread() -> None:
    """One BLAS thread, as dask's nannies give every worker. To be called before numpy is
    imported, and only when a benchmark runs as a program (never on import: tests import
    them). Two threads on this machine's two cores made the contact solves 1.1-3x slower
    and erratic (a dense solve's second thread waits for a core)."""
    for var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        os.environ.setdefault(var, "1")


def print_rows(rows: list[dict], *, as_json: bool = False) -> None:
    """The rows of a benchmark as JSON, or one ``key=value`` line each (floats to 3 digits)."""
    if as_json:
        print(json.dumps(rows, indent=2))
        return
    for r in rows:
        print("  ".join(f"{k}={v:.3g}" if isinstance(v, float) else f"{k}={v}" for k, v in r.items()))
