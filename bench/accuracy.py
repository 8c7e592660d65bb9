"""Accuracy against the exact annulus (what tests/solver/test_ring.py and test_stages.py check).

Ring in a 30-radii medium, K = 0.5, full slip: the cos 2θ moment and pressure errors
against :func:`solver.analytic.exact_ring` for thin to thick linings at the default
interface_size and two refinements, both loadings, with DOF and seconds.

    python -m bench.accuracy [--json]
"""
from __future__ import annotations

import argparse
import time

from bench import print_rows
from solver import run_case
from solver.analytic import cos2_amplitude, exact_ring, ring_in_medium_case


def row(t: float, h: float, loading: str) -> dict:
    t0 = time.perf_counter()
    ds = run_case(ring_in_medium_case(radii=30, K=0.5, thickness=t, h=h, loading=loading))
    seconds = time.perf_counter() - t0
    ex = exact_ring(1e5, 0.5, 5e7, 0.3, 3e10, 0.2, 2.5, 2.5 + t, loading=loading, interface="slip")
    return {"loading": loading, "t_over_a": t / 2.5, "interface_size": h, "dof": 2 * ds.sizes["node"],
            "seconds": seconds, "M2_error": cos2_amplitude(ds, ds.moment.values) / ex.M2 - 1,
            "p2_error": cos2_amplitude(ds, ds.contact_pressure.values) / ex.p2 - 1}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    rows = [row(t, h, "external") for t in (0.0625, 0.25, 0.625) for h in (0.2, 0.1, 0.05)]
    rows += [row(0.3, 0.1, "excavation")]
    print_rows(rows, as_json=args.json)


if __name__ == "__main__":
    main()
