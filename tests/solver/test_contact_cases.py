"""Contact patterns, the bolt search, and agreement of the two inner solvers."""
from __future__ import annotations

import numpy as np
import pytest

from solver import CaseSpec, NotConvergedError, SolverError, run_case
from solver.contact.bolt import solve_contact
from solver.model import TunnelModel
import solver.stages.contact as contact_stage

COARSE = dict(interface_size=0.2, far_size=6.0)


def unloaded(gap: float = 0.0, **solver) -> CaseSpec:
    """A heavy lining in a weightless, unloaded ground: only the lining weight acts."""
    return CaseSpec(geometry=dict(gap=gap), ground=dict(density=0.0), loads=dict(surface_load=0.0),
                    mesh=COARSE, solver=solver or dict())


def test_heavy_lining_in_unloaded_ground_rests_on_the_invert(kkt):
    ds = run_case(unloaded())
    kkt(ds)
    th, closed = ds.theta.values, ds.in_contact.values.astype(bool)
    assert closed[-1] and not closed[0]
    assert th[closed].min() > 80.0          # nothing touches in the upper half
    assert np.all(closed[th >= th[closed].min()])  # one contiguous zone down to the invert
    assert th[np.argmax(ds.contact_pressure.values)] > 135.0
    assert float(ds.gap[0]) > 0
    assert float(ds.bolt_theta) == 180.0


def test_partial_gap_closure_touches_only_around_the_invert(kkt):
    g0 = 0.005
    ds = run_case(unloaded(gap=g0))
    kkt(ds)
    th, closed = ds.theta.values, ds.in_contact.values.astype(bool)
    zone = th[closed]
    assert zone.max() == 180.0 and np.all(closed[th >= zone.min()])
    no_gap = run_case(unloaded())
    assert 0 < float(ds.contact_extent) < float(no_gap.contact_extent)
    # the lining sank through the clearance: its crown settles by more than g0 and the
    # crown gap opened to more than twice the clearance
    assert float(ds.crown_settlement) > g0
    assert float(ds.gap[0]) > 2 * g0
    # where open, the gap is positive and there is no pressure
    assert np.all(ds.gap.values[~closed] > 0) and np.all(ds.contact_pressure.values[~closed] == 0)


def test_low_lateral_ratio_opens_the_springline_of_a_stiff_lining(kkt):
    """K0 = 0: the hole widens sideways; a stiff lining cannot follow, a flexible one can."""
    base = dict(loads=dict(lateral_ratio=0.0), boundaries=dict(side="pressure", bottom="roller"), mesh=COARSE,
                excavation=dict(method="wished-in-place"))
    stiff = run_case(CaseSpec(lining=dict(young=3e10), **base))
    kkt(stiff)
    th, closed = stiff.theta.values, stiff.in_contact.values.astype(bool)
    assert closed[0] and closed[-1]
    assert not closed[np.argmin(np.abs(th - 90))]
    assert th[~closed].min() > 45 and th[~closed].max() < 135
    flexible = run_case(CaseSpec(lining=dict(young=2e8), **base))
    kkt(flexible)
    assert float(flexible.contact_extent) == pytest.approx(180.0)


@pytest.mark.parametrize("spec", [
    CaseSpec(mesh=COARSE),
    CaseSpec(loads=dict(lateral_ratio=0.0), boundaries=dict(side="pressure", bottom="roller"), mesh=COARSE,
             excavation=dict(method="wished-in-place")),
    CaseSpec(geometry=dict(gap=0.005), ground=dict(density=0.0), loads=dict(surface_load=0.0), mesh=COARSE),
], ids=["default", "springline-open", "gap"])
def test_uzawa_and_active_set_agree(spec, kkt):
    a = run_case(spec)
    u = run_case(spec.model_copy(update={"solver": spec.solver.model_copy(update={"inner": "uzawa"})}))
    kkt(a)
    kkt(u)
    p = a.contact_pressure.values
    np.testing.assert_allclose(u.contact_pressure.values, p, rtol=0, atol=1e-6 * p.max())
    for name in ("displacement_x", "displacement_y"):
        ref = a[name].values
        np.testing.assert_allclose(u[name].values, ref, rtol=0, atol=1e-6 * np.abs(ref).max())
    assert int(u.iterations) > int(a.iterations)


def test_uzawa_that_cannot_converge_raises():
    with pytest.raises(NotConvergedError, match="max_iterations"):
        run_case(CaseSpec(mesh=COARSE, solver=dict(inner="uzawa", max_iterations=3)))


def _dual(spec):
    model = TunnelModel(spec)
    return contact_stage.dual_problem(model, spec), model.mesh.interface.theta


@pytest.mark.parametrize("inner", ["active-set", "uzawa"])
def test_bolt_search_recovers_from_a_bad_first_guess(inner):
    """Start the search at the crown (where the heavy lining does not touch): the
    crown bolt pulls (λ_A < 0), is rejected, and the next guess gives the solution."""
    dual, theta = _dual(unloaded())
    good = solve_contact(dual, theta, inner=inner, tol=1e-10, max_iterations=100000)
    flipped = 180.0 - theta  # the search starts at the largest "theta": the crown
    bad = solve_contact(dual, flipped, inner=inner, tol=1e-10, max_iterations=100000)
    assert len(bad.trials) >= 2
    assert bad.trials[0].node == 0 and bad.trials[0].bolt_pressure < 0 and not bad.trials[0].accepted
    assert bad.trials[-1].accepted and bad.trials[-1].bolt_pressure >= 0
    np.testing.assert_allclose(bad.lam, good.lam, rtol=0, atol=1e-7 * good.lam.max())


def test_fixed_bolt_with_negative_reaction_is_reported_not_hidden(monkeypatch):
    """A bolt forced where the lining pulls on the ground: the solution breaks λ ≥ 0 at the
    bolt. It is never given as a result (a case fails with the KKT residual it reached); the
    solve itself says so (converged 0, residual > 1e-3) when asked past that guard."""
    with pytest.raises(SolverError, match="KKT residual"):
        run_case(unloaded(bolt=0.0))
    import solver.stages.solve as solve_module

    monkeypatch.setattr(solve_module, "accepted_residual", lambda tolerance: float("inf"))
    ds = run_case(unloaded(bolt=0.0))
    assert float(ds.bolt_theta) == 0.0
    assert float(ds.contact_pressure[0]) < 0
    assert int(ds.converged) == 0
    assert float(ds.kkt_residual) > 1e-3


def test_fixed_bolt_in_the_contact_zone_gives_the_solution(kkt):
    auto = run_case(unloaded())
    fixed = run_case(unloaded(bolt=170.0))
    kkt(fixed)
    assert abs(float(fixed.bolt_theta) - 170.0) < 2.0
    p = auto.contact_pressure.values
    np.testing.assert_allclose(fixed.contact_pressure.values, p, rtol=0, atol=1e-7 * p.max())


def test_search_that_finds_no_admissible_bolt_raises_after_trying_every_candidate(monkeypatch):
    """Theorem 3.3 guarantees an admissible bolt; if the inner solver ever contradicts it
    (here: forced), the search tries each candidate once and raises, never returning."""
    import solver.contact.bolt as contact
    from solver import NoAdmissibleBoltError

    dual, theta = _dual(unloaded())
    calls = []

    def always_pulling(dual, bolt, lam_init, *, tol, max_iter):
        calls.append(bolt)
        lam = np.ones(dual.m)
        lam[bolt] = -1.0
        return contact.InnerResult(lam, 1, True)

    monkeypatch.setitem(contact.INNER, "active-set", always_pulling)
    with pytest.raises(NoAdmissibleBoltError, match="no admissible bolt"):
        solve_contact(dual, theta, inner="active-set", tol=1e-8, max_iterations=10)
    candidates = np.flatnonzero(np.abs(dual.nu2) > 1e-12)
    assert sorted(calls) == sorted(candidates.tolist())


@pytest.mark.parametrize("gap", [0.0, 0.005])
def test_nnls_fallback_solves_the_same_bolted_problem(gap):
    """The active-set method's cycle guard (Lawson-Hanson on the reduced dual) gives
    the same pressures as the active-set iteration, balance included."""
    import solver.contact.bolt as contact

    dual, theta = _dual(unloaded(gap=gap))
    bolt = int(np.argmax(theta))
    exact = contact.active_set(dual, bolt, np.zeros(dual.m), tol=1e-10, max_iter=100)
    fallback = contact._nnls(dual, bolt, 0)
    p = exact.lam
    np.testing.assert_allclose(fallback.lam, p, rtol=0, atol=1e-8 * p.max())
    assert abs(dual.F2 + np.sum(dual.nu2 * dual.w * fallback.lam)) < 1e-10 * abs(dual.F2)
    assert fallback.lam[np.arange(dual.m) != bolt].min() >= 0


def _random_case(rng: np.random.Generator) -> CaseSpec:
    a = rng.uniform(2.0, 4.0)
    t = a * rng.choice([0.025, 0.05, 0.1, 0.2])
    gap = rng.choice([0.0, 0.0, 0.002, 0.01])
    depth = rng.uniform(3.0, 6.0) * (a + t)
    return CaseSpec(
        geometry=dict(inner_radius=a, thickness=t, gap=gap, depth=depth, width=depth + 4 * a,
                      height=depth + 5 * a),
        ground=dict(young=10 ** rng.uniform(7, 8.5), poisson=rng.uniform(0.2, 0.4), density=rng.uniform(1600, 2200)),
        lining=dict(young=10 ** rng.uniform(9.5, 10.6), density=rng.uniform(2000, 2600)),
        loads=dict(surface_load=rng.uniform(0, 2e5), lateral_ratio=rng.uniform(0.3, 1.5)),
        excavation=dict(method=rng.choice(["deconfinement", "wished-in-place"]),
                        deconfinement=rng.uniform(0, 0.9)),
        boundaries=dict(side=rng.choice(["roller", "fixed", "pressure"])),
        design=dict(reinforcement_area=0.0),
        mesh=dict(interface_size=0.2, far_size=8.0))


@pytest.mark.slow
def test_inner_solvers_agree_on_random_cases():
    """20 seeded random valid cases (thin linings, gaps, both loadings, every side): both
    inner solvers meet the KKT tolerance and agree to 1e-6 in λ, or Uzawa says it did not
    converge; one TunnelModel serves both solves of a case."""
    rng = np.random.default_rng(20261122)
    agreed = 0
    for _ in range(20):
        spec = _random_case(rng)
        model = TunnelModel(spec)
        exact = model.solve(spec)
        assert exact.kkt_residual <= spec.solver.tolerance
        try:
            uz = model.solve(spec.model_copy(update={"solver": spec.solver.model_copy(update={"inner": "uzawa"})}))
        except NotConvergedError as err:
            assert "did not converge" in str(err)
            continue
        assert uz.kkt_residual <= spec.solver.tolerance
        np.testing.assert_allclose(uz.lam, exact.lam, rtol=0, atol=1e-6 * exact.lam.max())
        agreed += 1
    assert agreed >= 15
