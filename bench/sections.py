"""What a section beyond the circle costs (SPEC §9.4), as ratios measured in one run.

The three-centre horseshoe of ``examples/horseshoe.json`` (crown 5.5 m over 100°, sides 3.5 m
over 50°, invert solved), elastic ground, against the circle of equal excavated area (same
lining thickness, depth, ground, loads, mesh settings): the whole ``run_case`` (mesh, assembly,
factorization, solve, dataset) and a further case on an already built model (a sweep's next
case: another K0), each the least of ``--repeat`` runs, the cases alternated so that a busy
machine slows them alike; the mesh sizes; and what the engineer reads: the largest thrust and
|M|, where the largest |M| sits, the largest contact pressure.

    python -m bench.sections [--repeat N] [--json]
"""
from __future__ import annotations

if __name__ == "__main__":
    from bench import one_blas_thread

    one_blas_thread()

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from solver import CaseSpec, run_case  # noqa: E402
from solver.model import TunnelModel  # noqa: E402

SHAPE = {"shape": "horseshoe", "crown_radius": 5.5, "crown_angle": 100.0, "side_radius": 3.5, "side_angle": 50.0}
BASE = {"geometry": {"thickness": 0.3, "depth": 25.0, "width": 60.0, "height": 70.0},
        "ground": {"young": 2.0e8, "density": 2200.0}, "loads": {"surface_load": 2.0e4, "lateral_ratio": 0.7}}


def cases() -> dict[str, CaseSpec]:
    """The horseshoe and the circle whose intrados encloses the same area plus the lining's
    ring: the circle of the horseshoe's excavated area, less the thickness."""
    horseshoe = CaseSpec.model_validate({**BASE, "geometry": {**BASE["geometry"], "section": SHAPE}})
    hole = horseshoe.geometry.hole_radius
    circle = CaseSpec.model_validate({**BASE, "geometry": {**BASE["geometry"], "inner_radius": hole - 0.3}})
    return {"circle": circle, "horseshoe": horseshoe}


def _next(spec: CaseSpec) -> CaseSpec:
    return spec.model_copy(update={"loads": spec.loads.model_copy(update={"lateral_ratio": 0.6})})


def measure(repeat: int) -> dict:
    specs = cases()
    whole = {name: math.inf for name in specs}
    nxt = {name: math.inf for name in specs}
    models = {name: TunnelModel(spec) for name, spec in specs.items()}
    for name, spec in specs.items():
        models[name].solve(_next(spec))
    results = {}
    for _ in range(repeat):
        for name, spec in specs.items():
            t0 = time.perf_counter()
            results[name] = run_case(spec)
            models[name].kept.forget()  # the next case solved, not taken from the last round
            t1 = time.perf_counter()
            models[name].solve(_next(spec))
            t2 = time.perf_counter()
            whole[name], nxt[name] = min(whole[name], t1 - t0), min(nxt[name], t2 - t1)
    out = {}
    for name, ds in results.items():
        k = int(np.argmax(np.abs(ds["moment"].values)))
        out[name] = {"run_case_s": whole[name], "ratio": whole[name] / whole["circle"], "next_case_s": nxt[name],
                     "next_ratio": nxt[name] / nxt["circle"], "faces": int(ds.sizes["face"]),
                     "stations": int(ds.sizes["interface"]),
                     "excavated_area_m2": math.pi * specs[name].geometry.hole_radius ** 2,
                     "max_thrust_kN": float(ds["max_thrust"]) / 1e3,
                     "max_abs_moment_kNm": float(ds["max_abs_moment"]) / 1e3,
                     "max_moment_theta_deg": float(ds["theta"][k]),
                     "max_contact_pressure_kPa": float(ds["max_contact_pressure"]) / 1e3}
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    out = measure(args.repeat)
    if args.json:
        print(json.dumps(out, indent=2))
        return
    print(f"{'case':10s} {'run_case s':>11s} {'/ circle':>9s} {'next s':>8s} {'/ circle':>9s} {'faces':>7s}"
          f" {'area m2':>8s} {'max N kN':>9s} {'max|M| kNm':>11s} {'at deg':>7s} {'max λ kPa':>10s}")
    for name, r in out.items():
        print(f"{name:10s} {r['run_case_s']:11.3f} {r['ratio']:9.2f} {r['next_case_s']:8.4f} {r['next_ratio']:9.2f}"
              f" {r['faces']:7d} {r['excavated_area_m2']:8.2f} {r['max_thrust_kN']:9.1f}"
              f" {r['max_abs_moment_kNm']:11.1f} {r['max_moment_theta_deg']:7.1f} {r['max_contact_pressure_kPa']:10.1f}")


if __name__ == "__main__":
    main()
