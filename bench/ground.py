"""What layered, water-bearing and yielding ground costs (SPEC §1.4, §1.5), as ratios measured in
one run.

At the default mesh: the whole ``run_case`` of the default (homogeneous, dry, elastic) case, of
the README's two-layer case with a water table 3 m down (watertight and drained), and the cost
of a further case on an already built model (a sweep over the water table or K0: no
meshing, assembly or factorization, only loads, forward / backward solves and the contact
solve; a drained case also solves its head problem, factorized once per table). The
Mohr–Coulomb case reports its plastic iterations (all increments of both stages). A further
case whose lining is lighter is timed too: yielding ground's stage 1 is then the one its model kept
(:func:`solver.stages.plastic._first_stage`), only stage 2 is solved (a case varying only the design
takes the kept mechanics whole: :meth:`solver.model.TunnelModel.solve`). Each
timing is the least of ``--repeat`` runs, alternating the cases so that a busy machine slows
them alike; ``paired`` is the median over the rounds of each case's time over the default's
in the same round. ``--weak`` also solves, once on its built model, issue 25's weak ground
(c 15 kPa, φ 25°, ψ 0: increments that stall and are split) and reports its iterations.

``--sample N`` instead solves a seeded Sobol' sample (scipy.stats.qmc) of N weak soft-ground cases
(c′ 1–15 kPa, φ′ 20–32°, ψ 0–5°, λd 0.2–0.6, K0 0.4–0.7, E 30–150 MPa log-uniform, default
geometry; issue 36), N of a wider range (c′ 5–50 kPa, φ′ 20–38°) and N weak rocks of generalized
Hoek–Brown ground (:func:`rock_cases`), each ``run_case`` timed
back to back with its elastic twin (the same case with elastic ground): the share that
converged (a collapse is named, with the deconfinement held), and the cost ratios' median, 95th
percentile and maximum; then issue 36's default Mohr–Coulomb case (c 10 kPa, φ 28°, ψ 0) against
the default, and a next case of it on its built model (K0 varied; the lining lighter).

``--edge N`` solves a seeded sample of N weak soft-ground cases released far (c′ 3–15 kPa, φ′ 20–32°, ψ 0–5°,
λd 0.7–0.95, K0 0.45–0.7) and reports each outcome and time: converged, or a collapse (the staged path's own, or
proved by Radenkovic's bounds: :mod:`solver.stages.bounds`), or a failure.

``--zones N`` solves the yielding cases (the two above, issue 36's default, the first N of each sampled family)
with the yielding zone (:mod:`solver.stages.region`) and on the whole ground, back to back: the speed-up and
how far the answers differ.

    python -m bench.ground [--repeat N] [--json] [--weak] [--sample N] [--edge N] [--zones N]
"""
from __future__ import annotations

if __name__ == "__main__":
    from bench import one_blas_thread

    one_blas_thread()

import argparse  # noqa: E402
import json  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402

from solver import CaseSpec, run_case  # noqa: E402
from solver.errors import GroundCollapseError, SolverError  # noqa: E402
from solver.model import TunnelModel  # noqa: E402
from solver.stages.loads import seepage as seepage_of  # noqa: E402

LAYERS = [{"thickness": 6.0, "young": 2.0e7, "density": 1900.0, "lateral_ratio": 0.6},
          {"thickness": 0.0, "young": 1.2e8, "density": 2100.0, "lateral_ratio": 0.45}]
#: issue 36's default Mohr–Coulomb case (≤ 3 times its elastic twin, the default)
MC_DEFAULT = {"ground": {"model": "mohr-coulomb", "cohesion": 1.0e4, "friction_angle": 28.0, "dilatancy": 0.0}}
CASES = {
    "default": {},
    "layered-watertight": {"ground": {"layers": LAYERS}, "water": {"table": 3.0}},
    "layered-drained": {"ground": {"layers": LAYERS}, "water": {"table": 3.0, "lining": "drained"}},
    "mohr-coulomb": {"ground": {"model": "mohr-coulomb", "cohesion": 3.0e4, "friction_angle": 28.0,
                                "tensile_strength": 1.0e4}},
    "mohr-coulomb-c10": MC_DEFAULT,
    # the README's default tunnel in weak rock (issue 36: ≤ 3.5 times its elastic twin, the next row)
    "hoek-brown": {"ground": {"model": "hoek-brown", "young": 5.0e8, "ucs": 1.0e6, "gsi": 30.0, "mi": 8.0,
                              "dilatancy": 5.0}},
    "hoek-brown-elastic": {"ground": {"young": 5.0e8}},
}
#: issue 25's weak ground under a thin stiff lining (the plastic iteration splits its stalled increments)
WEAK = {"ground": {"model": "mohr-coulomb", "cohesion": 1.5e4, "friction_angle": 25.0},
        "geometry": {"thickness": 0.2}, "lining": {"young": 1.0e10}}


def _least(fn, repeat: int) -> float:
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


#: the sampled families: (c′ kPa, φ′ deg) ranges; ψ 0–5°, λd 0.2–0.6, K0 0.4–0.7, E 30–150 MPa for both
FAMILIES = {"weak": ((1.0, 15.0), (20.0, 32.0)), "wide": ((5.0, 50.0), (20.0, 38.0))}


def sample_cases(n: int, family: str, seed: int = 36) -> list[dict]:
    """``n`` cases of a family from a scrambled Sobol' sequence (seeded: the same cases every run)."""
    from scipy.stats import qmc

    (c0, c1), (p0, p1) = FAMILIES[family]
    u = qmc.Sobol(d=6, scramble=True, seed=seed).random(n)
    lo, hi = [c0, p0, 0.0, 0.2, 0.4, 3.0e7], [c1, p1, 5.0, 0.6, 0.7, 1.5e8]
    cases = []
    for c, phi, psi, ld, k0, logE in qmc.scale(u, lo[:5] + [0.0], hi[:5] + [1.0]):
        young = lo[5] * (hi[5] / lo[5]) ** logE
        cases.append({"ground": {"young": round(young, -5), "model": "mohr-coulomb", "cohesion": round(c * 1e3, 1),
                                 "friction_angle": round(phi, 2), "dilatancy": round(min(psi, phi), 2)},
                      "loads": {"lateral_ratio": round(k0, 3)}, "excavation": {"deconfinement": round(ld, 3)}})
    return cases


def rock_cases(n: int, seed: int = 7) -> list[dict]:
    """``n`` weak-rock cases of generalized Hoek–Brown ground from a scrambled Sobol' sequence (seeded):
    σci 0.3–5 MPa log-uniform, GSI 10–40, mi 5–20, D 0–0.5, ψ 0–5°, K0 0.4–1.5, λd 0.2–0.7, E = 150 σci
    within 0.1–5 GPa; default geometry."""
    from scipy.stats import qmc

    u = qmc.Sobol(d=7, scramble=True, seed=seed).random(n)
    cases = []
    for a, gsi, mi, d, psi, k0, ld in qmc.scale(u, [0, 10, 5, 0, 0, 0.4, 0.2], [1, 40, 20, 0.5, 5, 1.5, 0.7]):
        ucs = 0.3e6 * (5.0e6 / 0.3e6) ** a
        cases.append({"ground": {"model": "hoek-brown", "young": round(min(max(150.0 * ucs, 1.0e8), 5.0e9), -5),
                                 "ucs": round(ucs, -3), "gsi": round(gsi, 1), "mi": round(mi, 1),
                                 "disturbance": round(d, 2), "dilatancy": round(psi, 2)},
                      "loads": {"lateral_ratio": round(k0, 3)}, "excavation": {"deconfinement": round(ld, 3)}})
    return cases


def _solve_again(model: TunnelModel, spec: CaseSpec):
    """``model.solve(spec)`` as a sweep's next case: the solutions the model kept (a case met before
    is not solved again) forgotten first, what it kept of other solves (stage 1) not."""
    model.kept.forget("solution")
    return model.solve(spec)


def _lighter_lining(spec: CaseSpec) -> CaseSpec:
    """``spec`` with a lining 10 % lighter: a sweep's next case that stage 1 does not depend on."""
    lighter = spec.lining.density * 0.9
    return spec.model_copy(update={"lining": spec.lining.model_copy(update={"density": lighter})})


def _twin(case: dict) -> dict:
    twin = json.loads(json.dumps(case))
    twin["ground"] = {"young": case["ground"]["young"]} if "young" in case["ground"] else {}
    return twin


def _timed(case: dict):
    from pydantic import ValidationError

    try:
        spec = CaseSpec.model_validate(case)
    except ValidationError as e:  # not a case: an in-situ state outside the yield surface is refused
        return float("nan"), f"refused: {e.errors()[0]['msg']}"
    t0 = time.perf_counter()
    try:
        ds = run_case(spec)
        warnings = ds.attrs.get("warnings", [])
        warnings = json.loads(warnings) if isinstance(warnings, str) else warnings
        # solved again at a tighter stop test (solver.stages.plastic.tightened), which its warnings say
        outcome = "retried" if any(w.startswith("solver.plastic_tolerance") for w in warnings) else "converged"
    except SolverError as e:
        outcome = f"collapse: {e}" if isinstance(e, GroundCollapseError) else f"failed: {e}"
    return time.perf_counter() - t0, outcome


def edge_cases(n: int, seed: int = 7) -> list[dict]:
    """``n`` weak soft-ground cases released far (``--edge``), from a scrambled Sobol' sequence (seeded)."""
    from scipy.stats import qmc

    u = qmc.Sobol(d=5, scramble=True, seed=seed).random(n)
    return [{"ground": {"model": "mohr-coulomb", "cohesion": round(c * 1e3, 1), "friction_angle": round(phi, 2),
                        "dilatancy": round(psi, 2)}, "loads": {"lateral_ratio": round(k0, 3)},
             "excavation": {"deconfinement": round(ld, 3)}}
            for c, phi, psi, ld, k0 in qmc.scale(u, [3, 20, 0, 0.7, 0.45], [15, 32, 5, 0.95, 0.7])]


def sample_study(n: int) -> dict:
    """Per family: outcomes and the cost over the elastic twin (see the module's docstring)."""
    import numpy as np

    run_case(CaseSpec.model_validate({}))  # warm the imports
    out = {}
    families = {**{family: sample_cases(n, family) for family in FAMILIES}, "rock": rock_cases(n)}
    for family, cases in families.items():
        rows = []
        for case in cases:
            plastic, outcome = _timed(case)
            if outcome.startswith("refused"):
                rows.append({"case": case, "outcome": outcome, "ratio": float("nan"), "seconds": 0.0})
                continue
            elastic, _ = _timed(_twin(case))
            rows.append({"case": case, "outcome": outcome, "ratio": plastic / elastic, "seconds": plastic})
        rows_run = [r for r in rows if not r["outcome"].startswith("refused")]
        ratios = np.array([r["ratio"] for r in rows_run])
        out[family] = {"cases": rows, "refused": len(rows) - len(rows_run),
                       "converged_or_collapse": float(np.mean([not r["outcome"].startswith("failed")
                                                               for r in rows_run])),
                       "collapses": sum(r["outcome"].startswith("collapse") for r in rows),
                       "retried": sum(r["outcome"] == "retried" for r in rows),
                       "median": float(np.median(ratios)), "p95": float(np.percentile(ratios, 95)),
                       "max": float(ratios.max())}
    elastic, _ = _timed({})
    plastic, outcome = _timed(MC_DEFAULT)
    spec = CaseSpec.model_validate(MC_DEFAULT)
    model = TunnelModel(spec)
    model.solve(spec)
    other = spec.model_copy(update={"loads": spec.loads.model_copy(update={"lateral_ratio": 0.6})})
    t0 = time.perf_counter()
    model.solve(other)
    t_next = time.perf_counter() - t0
    t0 = time.perf_counter()
    model.solve(_lighter_lining(spec))
    t_lighter = time.perf_counter() - t0
    out["mc_default"] = {"ratio": plastic / elastic, "outcome": outcome, "next_case_on_model_s": t_next,
                         "next_lighter_lining_s": t_lighter}
    return out


#: what the zone study compares: displacements and forces (relative), the yielded areas (m², within the
#: stop test's reach of the surface)
_MEASURES = ("crown_settlement", "max_thrust", "max_abs_moment", "ground_loss")


def zone_study(n: int) -> dict:
    """Each yielding case (the bench's two, issue 36's default and the first ``n`` of each sampled family)
    solved with the yielding zone (:mod:`solver.stages.region`) and on the whole ground, back to back: the
    time ratio and the largest relative difference of :data:`_MEASURES`."""
    import numpy as np

    from solver.stages import region

    cases = {"mohr-coulomb": CASES["mohr-coulomb"], "hoek-brown": CASES["hoek-brown"], "c 10 kPa": MC_DEFAULT}
    for family, sampled in ({**{f: sample_cases(n, f) for f in FAMILIES}, "rock": rock_cases(n)} if n else {}).items():
        cases.update({f"{family} {i}": case for i, case in enumerate(sampled)})
    run_case(CaseSpec.model_validate({}))  # warm the imports
    rows = {}
    for name, case in cases.items():
        try:
            spec = CaseSpec.model_validate(case)
        except ValueError:
            continue  # refused: its in-situ state outside the surface
        got = {}
        for enabled in (False, True):
            region.ENABLED = enabled
            t0 = time.perf_counter()
            try:
                ds = run_case(spec)
                got[enabled] = (time.perf_counter() - t0, {k: float(ds[k]) for k in _MEASURES + ("plastic_area",)})
            except SolverError as e:
                got[enabled] = (time.perf_counter() - t0, str(e)[:80])
            finally:
                region.ENABLED = True
        (t_whole, whole), (t_zone, zone) = got[False], got[True]
        row = {"whole_s": t_whole, "zone_s": t_zone, "speedup": t_whole / t_zone}
        if isinstance(whole, dict) and isinstance(zone, dict):
            row["largest_difference"] = max(abs(zone[k] - whole[k]) / max(abs(whole[k]), 1e-12) for k in _MEASURES)
            row["area_difference_m2"] = abs(zone["plastic_area"] - whole["plastic_area"])
        else:
            row["outcome"] = f"whole: {whole if isinstance(whole, str) else 'ok'}; zone: " \
                             f"{zone if isinstance(zone, str) else 'ok'}"
        rows[name] = row
    speedups = np.array([r["speedup"] for r in rows.values()])
    return {"cases": rows, "median_speedup": float(np.median(speedups)), "least_speedup": float(speedups.min()),
            "total_whole_s": sum(r["whole_s"] for r in rows.values()),
            "total_zone_s": sum(r["zone_s"] for r in rows.values())}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--weak", action="store_true", help="also solve issue 25's weak ground once")
    ap.add_argument("--sample", type=int, default=0, help="solve a seeded sample of this many cases per family")
    ap.add_argument("--zones", type=int, default=0,
                    help="time the yielding zone against the whole ground on this many cases per family")
    ap.add_argument("--edge", type=int, default=0, help="solve a seeded sample of this many weak grounds released far")
    args = ap.parse_args(argv)
    if args.edge:
        run_case(CaseSpec.model_validate({}))  # warm the imports
        for case in edge_cases(args.edge):
            seconds, outcome = _timed(case)
            print(f"{seconds:7.1f} s  {json.dumps(case)}: {outcome[:300]}", flush=True)
        return
    if args.zones:
        study = zone_study(args.zones)
        if args.json:
            print(json.dumps(study, indent=2))
            return
        for name, r in study["cases"].items():
            print(f"{name:12s} whole {r['whole_s']:7.2f} s  zone {r['zone_s']:7.2f} s  x{r['speedup']:.2f}  "
                  + (f"largest difference {r['largest_difference']:.1e}, yielded area {r['area_difference_m2']:.3f} m2"
                     if "largest_difference" in r else r["outcome"]))
        print(f"zone over whole ground: median speed-up {study['median_speedup']:.2f}, least "
              f"{study['least_speedup']:.2f}; in all {study['total_whole_s']:.1f} s -> {study['total_zone_s']:.1f} s")
        return
    if args.sample:
        study = sample_study(args.sample)
        if args.json:
            print(json.dumps(study, indent=2))
            return
        for family in (*FAMILIES, "rock"):
            r = study[family]
            print(f"{family}: {100 * r['converged_or_collapse']:.0f} % converged or named collapse "
                  f"({r['collapses']} collapses, {r['retried']} solved again at half the tolerance, "
                  f"{r['refused']} refused as inadmissible); "
                  f"cost / elastic twin: median {r['median']:.2f}, "
                  f"95th percentile {r['p95']:.2f}, max {r['max']:.2f}")
            for row in r["cases"]:
                print(f"  {json.dumps(row['case'])}: {row['outcome'][:120]}, {row['ratio']:.2f}x")
        d = study["mc_default"]
        print(f"default Mohr-Coulomb (c 10 kPa, phi 28, psi 0): {d['ratio']:.2f}x elastic ({d['outcome'][:80]}); "
              f"next case on its built model {d['next_case_on_model_s']:.3f} s (K0 varied), "
              f"{d['next_lighter_lining_s']:.3f} s (the lining lighter: stage 1 kept)")
        return
    specs = {name: CaseSpec.model_validate(d) for name, d in CASES.items()}
    whole = {name: float("inf") for name in specs}
    rounds = []
    for _ in range(args.repeat):
        times = {}
        for name, spec in specs.items():
            t0 = time.perf_counter()
            run_case(spec)
            times[name] = time.perf_counter() - t0
            whole[name] = min(whole[name], times[name])
        rounds.append(times)
    on_model, on_lighter, iterations, seepage = {}, {}, {}, {}
    for name, spec in specs.items():
        model = TunnelModel(spec)
        first = model.solve(spec)
        if first.plastic is not None:
            iterations[name] = first.plastic["iterations"]
        table = spec.water.table
        other = spec if table is None else spec.model_copy(
            update={"water": spec.water.model_copy(update={"table": table + 1.0})})
        if first.plastic is not None or spec.drained:  # a sweep's next case: another K0 (a drained
            # case's table is a line of its mesh: another table is another model; a yielding ground's
            # stage 1 is kept per K0)
            other = spec.model_copy(update={"loads": spec.loads.model_copy(update={"lateral_ratio": 0.6})})
        model.solve(other)  # a drained case solves its seepage once per model
        on_model[name] = _least(lambda: _solve_again(model, other), args.repeat)
        # a sweep over the lining's weight (or the interface's strength): yielding ground's stage 1
        # is the kept one, only stage 2 is solved
        on_lighter[name] = _least(lambda: _solve_again(model, _lighter_lining(spec)), args.repeat)
        if spec.drained:
            seepage[name] = _least(lambda: (model._seepage.clear(), seepage_of(model, spec)), args.repeat)
    rows = {name: {"run_case_s": whole[name], "ratio_to_default": whole[name] / whole["default"],
                   "paired_ratio": statistics.median(r[name] / r["default"] for r in rounds),
                   "next_case_on_model_s": on_model[name],
                   "next_ratio": on_model[name] / on_model["default"],
                   "next_lighter_lining_s": on_lighter[name],
                   "plastic_iterations": iterations.get(name), "seepage_s": seepage.get(name)} for name in specs}
    weak = None
    if args.weak:
        spec = CaseSpec.model_validate(WEAK)
        model = TunnelModel(spec)
        t0 = time.perf_counter()
        try:
            weak = {"iterations": model.solve(spec).plastic["iterations"]}
        except SolverError as e:
            weak = {"failed": str(e)}
        weak["solve_s"] = time.perf_counter() - t0
    if args.json:
        print(json.dumps({"cases": rows, "weak": weak} if args.weak else rows, indent=2))
        return
    print(f"{'case':22s} {'run_case s':>11s} {'/ default':>10s} {'paired':>7s} {'next case on model s':>21s}"
          f" {'/ default':>10s} {'next, lining lighter s':>23s} {'plastic iterations':>19s}")
    for name, r in rows.items():
        print(f"{name:22s} {r['run_case_s']:11.3f} {r['ratio_to_default']:10.2f} {r['paired_ratio']:7.2f}"
              f" {r['next_case_on_model_s']:21.4f} {r['next_ratio']:10.1f} {r['next_lighter_lining_s']:23.4f}"
              f" {r['plastic_iterations'] or '':>19}")
    for name, seconds in seepage.items():
        print(f"{name}: the unconfined seepage alone (Picard, on the built model) {seconds:.3f} s")
    hb, twin = rows["hoek-brown"], rows["hoek-brown-elastic"]
    print(f"hoek-brown against its elastic twin: run_case {hb['run_case_s'] / twin['run_case_s']:.2f}x, "
          f"next case on its model {hb['next_case_on_model_s'] / twin['next_case_on_model_s']:.2f}x, "
          f"the lining lighter {hb['next_lighter_lining_s'] / twin['next_lighter_lining_s']:.2f}x")
    if weak is not None:
        print(f"weak ground (issue 25), solve on its built model: {weak['solve_s']:.2f} s, "
              + (f"{weak['iterations']} plastic iterations" if "iterations" in weak else weak["failed"]))


if __name__ == "__main__":
    main()
