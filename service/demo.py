"""Demo: start the service, run a sweep through its REST API, show and save the results.

``python -m service.demo [--results DIR] [--sweep SWEEP.json]``

Starts ``tunnel-contact serve`` on a free loopback port with an embedded dask cluster,
waits for ``/health``, posts a sweep (``examples/sweep.json``, else a built-in one of
six cases varying the lining thickness and the ground stiffness), follows it with a
progress bar, prints the comparison table, saves the combined netCDF and the plots
under ``<results>/demo/`` and stops the service (also on Ctrl-C or an error).
"""
from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from pathlib import Path

import httpx
from tqdm import tqdm

from workflows.commands import comparison_table
from workflows.parameters import flat_parameters
from workflows.plots import PLOTS

from .process import running_service

logger = logging.getLogger(__name__)

EXAMPLE = Path(__file__).resolve().parent.parent / "examples" / "sweep.json"
BUILT_IN_SWEEP = {
    "name": "demo-thickness-stiffness",
    "base": {},
    "vary": {"lining.thickness": [0.2, 0.3, 0.4], "ground.young": [2.0e7, 5.0e7]},
    "mode": "grid",
}


def load_sweep(path: Path | None) -> dict:
    """The sweep to run: ``path``, else ``examples/sweep.json``, else the built-in one."""
    for candidate in (path, EXAMPLE):
        if candidate is not None and candidate.is_file():
            return json.loads(candidate.read_text())
    return BUILT_IN_SWEEP


def follow(http: httpx.Client, sweep: dict, *, interval: float = 0.3) -> dict:
    """Poll the sweep until no case is queued or running, with a progress bar; return its status."""
    with tqdm(total=len(sweep["case_ids"]), desc=f"sweep {sweep['name']}", unit="case") as bar:
        while True:
            status = http.get(f"/sweeps/{sweep['id']}").raise_for_status().json()
            counts = status["counts"]
            bar.n = counts["done"] + counts["failed"]
            bar.set_postfix(running=counts["running"], queued=counts["queued"], failed=counts["failed"])
            bar.refresh()
            if status["finished"]:
                return status
            time.sleep(interval)


def table_rows(http: httpx.Client, case_ids: list[str]) -> list[dict]:
    """:func:`workflows.commands.comparison_table` rows from the cases' records."""
    rows = []
    for case_id in case_ids:
        case = http.get(f"/cases/{case_id}").raise_for_status().json()
        rows.append({"case_id": case_id, "status": case["status"], "error": case["error"],
                     "params": flat_parameters(case["spec"]), "summary": case["summary"] or {}})
    return rows


def save(http: httpx.Client, url: str, path: Path) -> Path:
    """Download ``url`` to ``path``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(http.get(url).raise_for_status().content)
    return path


def run_demo(results: Path, sweep_body: dict) -> int:
    """Run the whole demo against a fresh service process; return the exit code."""
    results = results.resolve()
    out = results / "demo"
    out.mkdir(parents=True, exist_ok=True)
    print(f"starting the service (log: {out / 'service.log'}) ...")
    with running_service(results, log=out / "service.log") as url:
        with httpx.Client(base_url=url, timeout=120) as http:
            health = http.get("/health").json()
            print(f"service at {url}: {health['workers']} workers, scheduler {health['scheduler']}")
            sweep = http.post("/sweeps", json=sweep_body).raise_for_status().json()
            print(f"POST /sweeps -> {sweep['id']} ({len(sweep['case_ids'])} cases, "
                  f"{sweep['new_cases']} new)")
            status = follow(http, sweep)
            print()
            print(comparison_table(table_rows(http, sweep["case_ids"])))
            print()
            if status["counts"]["done"] == 0:
                print("no case finished; nothing to save")
                return 1
            combined = save(http, f"/sweeps/{sweep['id']}/result.nc", out / f"{sweep['name']}.nc")
            print(f"combined results: {combined}")
            for case_id in sweep["case_ids"]:
                for name in PLOTS:
                    response = http.get(f"/cases/{case_id}/plots/{name}.png")
                    if response.status_code == 200:
                        (out / "plots").mkdir(exist_ok=True)
                        (out / "plots" / f"{case_id}_{name}.png").write_bytes(response.content)
            print(f"plots: {out / 'plots'} ({len(list((out / 'plots').glob('*.png')))} files)")
    print("service stopped")
    return 0 if status["counts"]["failed"] == 0 else 1


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m service.demo", description=__doc__.splitlines()[0])
    parser.add_argument("--results", type=Path, default=Path("results"), help="results directory (./results)")
    parser.add_argument("--sweep", type=Path, default=None, help="sweep JSON (default: examples/sweep.json)")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    try:
        return run_demo(args.results, load_sweep(args.sweep))
    except KeyboardInterrupt:
        print("\ninterrupted; service stopped", file=sys.stderr)
        return 130
    except (httpx.HTTPError, RuntimeError) as exc:
        print(f"demo failed: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
