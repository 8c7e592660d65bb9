"""What a segmental lining costs (SPEC §1.6), as ratios measured in one run.

At the default mesh: the whole ``run_case`` (mesh, assembly, factorization, solve, dataset)
of the default monolithic case and of the same case with six segments (0.15 m strips, bonded
and Coulomb joints), and a further case on an already built model (a sweep's next case:
another K0). Each timing is the least of ``--repeat`` runs, the cases alternated so that a
busy machine slows them alike. The issue's target: six segments at most twice the monolithic
case.

Then the study the README reads: the largest |M| of the default case against the number of
segments and the strip height, beside Muir Wood's reduced-stiffness rule of practice (the
monolithic ring's moment times the ratio of Einstein & Schwartz's full-slip moments with
I_e = I (4/n)² and with I).

With ``--convergence`` (issue 37): the joint forces, eccentricities and the ring's max |M| of three
patterns at the default mesh against a joint refinement four times finer (``JOINT_EDGE / 4``) and
a mesh of every size divided by four (``interface_size / 4``, the joints' refinement with it).

    python -m bench.joints [--repeat N] [--json] [--study] [--convergence]
"""
from __future__ import annotations

if __name__ == "__main__":
    from bench import one_blas_thread

    one_blas_thread()

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from solver import CaseSpec, run_case  # noqa: E402
from solver.analytic import einstein_schwartz_slip_excavation  # noqa: E402
from solver.model import TunnelModel  # noqa: E402
from solver.lining.forces import lining_forces  # noqa: E402

SIX = {"count": 6, "contact_height": 0.15}
CASES = {
    "monolithic": {},
    "six-bonded": {"lining": {"joints": SIX}},
    "six-coulomb": {"lining": {"joints": {**SIX, "shear": "coulomb", "friction": 0.5}}},
}


def _next(spec: CaseSpec) -> CaseSpec:
    return spec.model_copy(update={"loads": spec.loads.model_copy(update={"lateral_ratio": 0.6})})


def timings(repeat: int) -> dict:
    specs = {name: CaseSpec.model_validate(d) for name, d in CASES.items()}
    whole = {name: float("inf") for name in specs}
    nxt = {name: float("inf") for name in specs}
    models = {name: TunnelModel(spec) for name, spec in specs.items()}
    for name, spec in specs.items():
        models[name].solve(_next(spec))
    for _ in range(repeat):
        for name, spec in specs.items():
            t0 = time.perf_counter()
            run_case(spec)
            models[name].kept.forget()  # the next case solved, not taken from the last round
            t1 = time.perf_counter()
            models[name].solve(_next(spec))
            t2 = time.perf_counter()
            whole[name], nxt[name] = min(whole[name], t1 - t0), min(nxt[name], t2 - t1)
    return {name: {"run_case_s": whole[name], "ratio": whole[name] / whole["monolithic"],
                   "next_case_s": nxt[name], "next_ratio": nxt[name] / nxt["monolithic"]} for name in specs}


def max_moment(case: dict) -> tuple[float, float]:
    """Largest |M| (N·m/m) of the lining and largest joint opening (m) of a case."""
    spec = CaseSpec.model_validate(case)
    model = TunnelModel(spec)
    sol = model.solve(spec)
    f = lining_forces(spec, model.lining.body, model.mesh.interface, model.mesh.center, sol.u_lining, sol.lam,
                      sol.shear)
    return float(np.abs(f.moment).max()), float(sol.joints.opening.max()) if sol.joints is not None else 0.0


def muir_wood_factor(spec: CaseSpec, n: int) -> float:
    """Muir Wood's rule (I_e = I_j + I (4/n)², I_j = 0, n > 4) as the ratio of Einstein &
    Schwartz's full-slip cos 2θ moments with I_e and with I (the axial stiffness kept): the
    bending stiffness enters through F ∝ 1/I alone, so the thickness that gives I_e is used
    in F and the true one in C."""
    g, s = spec.geometry, spec.ground
    R, t = g.inner_radius + 0.5 * g.thickness, g.thickness
    full = einstein_schwartz_slip_excavation(1.0, spec.loads.lateral_ratio, s.young, s.poisson,
                                             spec.lining.young, spec.lining.poisson, R, t)[0]
    k = min(1.0, (4.0 / n) ** 2)
    # M2 depends on F only; F = E R³(1-νl²)/(El I (1-ν²)) with I -> k I is the lining modulus times k
    reduced = einstein_schwartz_slip_excavation(1.0, spec.loads.lateral_ratio, s.young, s.poisson,
                                                k * spec.lining.young, spec.lining.poisson, R, t)[0]
    return reduced / full


def study() -> dict:
    base = CaseSpec.model_validate({})
    mono, _ = max_moment({})
    rows = []
    for n in (4, 5, 6, 8, 10):
        for offset in (0.0, 180.0 / n):
            for a in (0.3, 0.15):
                m, opening = max_moment({"lining": {"joints": {"count": n, "offset": offset, "contact_height": a}}})
                rows.append({"segments": n, "offset_deg": offset, "strip_m": a, "max_abs_moment_kNm": m / 1e3,
                             "ratio_to_monolithic": m / mono, "muir_wood_ratio": muir_wood_factor(base, n),
                             "max_opening_mm": opening * 1e3})
    return {"monolithic_max_abs_moment_kNm": mono / 1e3, "rows": rows}


PATTERNS = {"6, 0°, a = t/2": {"count": 6, "offset": 0.0, "contact_height": 0.15},
            "6, 30°, a = t/2": {"count": 6, "offset": 30.0, "contact_height": 0.15},
            "6, 0°, a = t": {"count": 6, "offset": 0.0, "contact_height": 0.3}}


def _joint_values(joints: dict, interface_size: float = 0.1) -> dict:
    ds = run_case(CaseSpec.model_validate({"lining": {"joints": joints}, "mesh": {"interface_size": interface_size}}))
    return {"theta": ds["joint_theta"].values.tolist(), "moment_kNm": (ds["joint_moment"].values / 1e3).tolist(),
            "thrust_kN": (ds["joint_thrust"].values / 1e3).tolist(),
            "eccentricity": ds["joint_eccentricity"].values.tolist(),
            "max_abs_moment_kNm": float(ds["max_abs_moment"]) / 1e3, "seconds": float(ds["solve_seconds"])}


def convergence() -> dict:
    """Each pattern at the default mesh, with JOINT_EDGE / 4 and with interface_size / 4."""
    import solver.geometry.joints as joint_mesh

    out = {}
    for name, joints in PATTERNS.items():
        row = {"default": _joint_values(joints)}
        edge = joint_mesh.JOINT_EDGE
        joint_mesh.JOINT_EDGE = edge / 4.0
        try:
            row["joint_edge/4"] = _joint_values(joints)
        finally:
            joint_mesh.JOINT_EDGE = edge
        row["interface_size/4"] = _joint_values(joints, 0.025)
        out[name] = row
    return out


def _print_convergence(conv: dict) -> None:
    print("\njoint M (kN·m/m) and e/(a/2) at the default mesh; relative change to the finer meshes")
    for name, row in conv.items():
        d = row["default"]
        print(f"{name}: run_case {d['seconds']:.1f} s (joint_edge/4 {row['joint_edge/4']['seconds']:.1f} s, "
              f"interface_size/4 {row['interface_size/4']['seconds']:.1f} s)")
        for j, theta in enumerate(d["theta"]):
            cells = [f"{theta:5.0f}°  M {d['moment_kNm'][j]:8.2f}  e {d['eccentricity'][j]:.4f}"]
            for ref in ("joint_edge/4", "interface_size/4"):
                r = row[ref]
                cells.append(f"{ref}: M {r['moment_kNm'][j]:8.2f} ({d['moment_kNm'][j] / r['moment_kNm'][j] - 1:+.2%})"
                             f" e {r['eccentricity'][j]:.4f} ({d['eccentricity'][j] / r['eccentricity'][j] - 1:+.2%})")
            print("   " + "   ".join(cells))
        for ref in ("joint_edge/4", "interface_size/4"):
            print(f"   max |M| {d['max_abs_moment_kNm']:.2f} vs {ref} {row[ref]['max_abs_moment_kNm']:.2f} "
                  f"({d['max_abs_moment_kNm'] / row[ref]['max_abs_moment_kNm'] - 1:+.2%})")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--study", action="store_true", help="also the moment study over segments and strip height")
    ap.add_argument("--convergence", action="store_true", help="also the joints against finer meshes (issue 37)")
    args = ap.parse_args(argv)
    out = {"timings": timings(args.repeat)}
    if args.study:
        out["study"] = study()
    if args.convergence:
        out["convergence"] = convergence()
    if args.json:
        print(json.dumps(out, indent=2))
        return
    print(f"{'case':14s} {'run_case s':>11s} {'/ monolithic':>13s} {'next case s':>12s} {'/ monolithic':>13s}")
    for name, r in out["timings"].items():
        print(f"{name:14s} {r['run_case_s']:11.3f} {r['ratio']:13.2f} {r['next_case_s']:12.4f} {r['next_ratio']:13.2f}")
    if args.study:
        s = out["study"]
        print(f"\nmonolithic max |M| {s['monolithic_max_abs_moment_kNm']:.1f} kN·m/m")
        print(f"{'n':>3s} {'offset':>7s} {'a m':>5s} {'max |M| kNm':>12s} {'/ mono':>7s} {'Muir Wood':>10s}"
              f" {'opening mm':>11s}")
        for r in s["rows"]:
            print(f"{r['segments']:3d} {r['offset_deg']:7.1f} {r['strip_m']:5.2f} {r['max_abs_moment_kNm']:12.1f}"
                  f" {r['ratio_to_monolithic']:7.2f} {r['muir_wood_ratio']:10.2f} {r['max_opening_mm']:11.2f}")
    if args.convergence:
        _print_convergence(out["convergence"])


if __name__ == "__main__":
    main()
