"""Demo: the default case, then three lining thicknesses on an embedded dask cluster.

Run ``python -m workflows.demo`` (or ``make demo``); results go to ``./results`` and
a comparison table is printed. Cases already stored are not recomputed.
"""
from __future__ import annotations

import logging
import sys

from solver import CaseSpec

from .commands import case_row, comparison_table, configure_logging
from .plots import plot_comparison
from .store import run_and_store
from .sweep import Sweep, run_sweep

logger = logging.getLogger(__name__)

RESULTS = "results"
#: The comparison the demo runs: lining thickness 0.2, 0.3, 0.4 m, everything else default.
DEMO_SWEEP = Sweep(name="demo-lining-thickness", vary={"lining.thickness": [0.2, 0.3, 0.4]})


def main(results: str = RESULTS) -> int:
    """Run the demo into ``results``; return 0 if every case was solved."""
    from pathlib import Path

    from .combine import open_results

    configure_logging()
    default_id = run_and_store(CaseSpec(), results)
    print(f"default case {default_id} stored in {results}/cases/")
    case_ids = run_sweep(DEMO_SWEEP, results, progress=True)
    rows = [case_row(results, c) for c in dict.fromkeys([default_id, *case_ids])]
    print(comparison_table(rows))
    done = [r["case_id"] for r in rows if r["status"] == "done"]
    figure = Path(results) / "plots" / "demo_contact_pressure.png"
    figure.parent.mkdir(parents=True, exist_ok=True)
    plot_comparison(open_results(results, done)).savefig(figure, dpi=120)
    print(f"comparison plot: {figure}")
    logger.info("demo done: %d of %d cases", len(done), len(rows))
    return 0 if len(done) == len(rows) else 1


if __name__ == "__main__":
    sys.exit(main())
