"""Accuracy figures against the closed-form ring solutions (what tests/solver/test_ring.py checks).

    python -m bench.accuracy [--json]
"""
from __future__ import annotations

import argparse
import json

import numpy as np

from solver import run_case
from solver.analytic import ring_in_medium_case, ring_pressure, thin_ring_cos2


def _means(ds) -> tuple[float, float]:
    w = ds.weight.values
    th = np.radians(ds.theta.values)
    return float(np.sum(w * ds.contact_pressure.values) / np.sum(w)), float(np.trapezoid(ds.thrust.values, th) / np.pi)


def hydrostatic(radii: float, young_l: float, h: float) -> dict:
    ds = run_case(ring_in_medium_case(radii=radii, K=1.0, young_l=young_l, h=h))
    q = ring_pressure(1e5, 5e7, 0.3, young_l, 0.2, 2.5, 2.8)
    qm, nm = _means(ds)
    return {"case": "K=1", "radii": radii, "E_lining": young_l, "h": h, "dof": 2 * ds.sizes["node"],
            "pressure_error": qm / q - 1, "thrust_error": nm / (q * 2.8) - 1}


def anisotropic(h: float, t: float = 0.3) -> dict:
    ds = run_case(ring_in_medium_case(radii=40, K=0.5, thickness=t, h=h))
    th = np.radians(ds.theta.values)
    M2, p2 = thin_ring_cos2(1e5, 0.5, 5e7, 0.3, 3e10, 0.2, 2.5 + t / 2, t)

    def cos2(f):
        return -2 * np.trapezoid(f * np.cos(2 * th), th) / np.pi

    return {"case": "K=0.5", "radii": 40, "E_lining": 3e10, "h": h, "dof": 2 * ds.sizes["node"],
            "p2_error": cos2(ds.contact_pressure.values) / p2 - 1, "M2_error": cos2(ds.moment.values) / M2 - 1,
            "thin_ring_error_estimate": t / (2 * (2.5 + t / 2))}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    rows = [hydrostatic(15, e, 0.1) for e in (3e10, 5e8)]
    rows += [hydrostatic(40, 5e8, h) for h in (0.2, 0.1, 0.05)]
    rows += [anisotropic(h) for h in (0.05, 0.0375, 0.025)]
    if args.json:
        print(json.dumps(rows, indent=2))
        return
    for r in rows:
        print("  ".join(f"{k}={v:.3g}" if isinstance(v, float) else f"{k}={v}" for k, v in r.items()))


if __name__ == "__main__":
    main()
