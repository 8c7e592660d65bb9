"""Benchmarks: each module is ``python -m bench.<name>`` and prints one run's figures."""
from __future__ import annotations

import json


def print_rows(rows: list[dict], *, as_json: bool = False) -> None:
    """The rows of a benchmark as JSON, or one ``key=value`` line each (floats to 3 digits)."""
    if as_json:
        print(json.dumps(rows, indent=2))
        return
    for r in rows:
        print("  ".join(f"{k}={v:.3g}" if isinstance(v, float) else f"{k}={v}" for k, v in r.items()))
