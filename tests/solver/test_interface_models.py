"""Interface models (SPEC §1.2): Coulomb friction between its limits, the bonded tie, a gap."""
from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from solver import CaseSpec, run_case
from solver.contact import friction
from solver.analytic import (
    cos2_amplitude,
    exact_ring,
    interface_mean,
    ring_in_medium_case,
)
from solver.errors import field_errors
from solver.model import TunnelModel
import solver.stages.contact as contact_stage

P, K, E, NU, E_L, NU_L, A, B = 1.0e5, 0.5, 5.0e7, 0.3, 3e10, 0.2, 2.5, 2.8
RADII = 30


def ring(loading: str, interface: str, friction: float = 0.0) -> CaseSpec:
    return ring_in_medium_case(radii=RADII, K=K, loading=loading, interface=interface, friction=friction)


@pytest.fixture(scope="module")
def ring_models():
    return {loading: TunnelModel(ring(loading, "bonded")) for loading in ("external", "excavation")}


@pytest.fixture(scope="module")
def solve_ring(ring_models):
    cache = {}

    def solve(loading: str, interface: str, friction: float = 0.0):
        key = (loading, interface, friction)
        if key not in cache:
            cache[key] = run_case(ring(loading, interface, friction), model=ring_models[loading])
        return cache[key]

    return solve


@pytest.fixture(scope="module")
def default_model():
    return TunnelModel(CaseSpec())


def with_interface(spec: CaseSpec, **interface) -> CaseSpec:
    return CaseSpec.model_validate({**spec.model_dump(), "interface": interface})


@pytest.mark.parametrize("loading", ["external", "excavation"])
def test_bonded_matches_exact_no_slip_ring(loading, solve_ring):
    ds = solve_ring(loading, "bonded")
    exact = exact_ring(P, K, E, NU, E_L, NU_L, A, B, loading=loading, interface="bonded")
    assert interface_mean(ds, ds.thrust.values) == pytest.approx(exact.N0, rel=0.01)
    assert cos2_amplitude(ds, ds.thrust.values) == pytest.approx(exact.N2, rel=0.03)
    assert cos2_amplitude(ds, ds.moment.values) == pytest.approx(exact.M2, rel=0.03)
    # the tie: no jumps, shear present
    assert np.max(np.abs(ds.tangential_jump.values)) <= 1e-9 * np.max(np.abs(ds.displacement_y.values))
    assert cos2_amplitude(ds, ds.contact_pressure.values) == pytest.approx(exact.p2, rel=0.03)
    assert float(ds.kkt_residual) <= 1e-8


def test_bonded_needs_no_bolt(solve_ring):
    ds = solve_ring("excavation", "bonded")
    assert int(ds.bolt_trials) == 0
    assert np.isnan(float(ds.bolt_theta))
    assert int(ds.slipping.sum()) == 0


def test_vanishing_friction_reproduces_frictionless(default_model, kkt):
    spec = CaseSpec()
    free = run_case(spec, model=default_model)
    slick = run_case(with_interface(spec, model="coulomb", friction=1e-6), model=default_model)
    kkt(free)
    kkt(slick)
    M0 = free.moment.values
    assert np.max(np.abs(slick.moment.values - M0)) <= 1e-3 * np.max(np.abs(M0))
    assert np.max(np.abs(slick.shear_traction.values)) <= 1e-5 * float(free.max_contact_pressure)


def test_large_friction_reproduces_bonded_in_full_compression(solve_ring, kkt):
    bonded = solve_ring("external", "bonded")
    assert bonded.contact_pressure.min() > 0.5 * interface_mean(bonded, bonded.contact_pressure.values)
    sticky = solve_ring("external", "coulomb", 5.0)
    kkt(sticky)
    N = bonded.thrust.values
    assert np.max(np.abs(sticky.thrust.values - N)) <= 0.01 * np.max(np.abs(N))
    assert int(sticky.slipping.sum()) == 0


@pytest.mark.parametrize("loading", ["external", "excavation"])
def test_moderate_friction_is_coulomb_and_between_the_limits(loading, solve_ring, kkt):
    mu = 0.3
    ds = solve_ring(loading, "coulomb", mu)
    kkt(ds)
    lam, s = ds.contact_pressure.values, ds.shear_traction.values
    jt, slipping = ds.tangential_jump.values, ds.slipping.values.astype(bool)
    p_ref = lam.max()
    assert np.all(np.abs(s) <= mu * lam + 1e-9 * p_ref)                       # the cone
    assert 0 < slipping.sum() < slipping.size - 2                              # both stick and slip
    np.testing.assert_allclose(np.abs(s[slipping]), mu * lam[slipping], rtol=1e-8)   # slip on the cone
    assert np.all(jt[slipping] * s[slipping] > 0)                              # [u]τ along s
    stick = ~slipping
    u_ref = np.max(np.abs(jt))
    assert np.max(np.abs(jt[stick])) <= 1e-6 * u_ref                            # stick: no jump
    n2 = cos2_amplitude(ds, ds.thrust.values)
    lo, hi = (exact_ring(P, K, E, NU, E_L, NU_L, A, B, loading=loading, interface=i).N2
              for i in ("slip", "bonded"))
    assert min(lo, hi) < n2 < max(lo, hi)
    assert float(ds.kkt_residual) <= 1e-8


def test_default_case_with_friction_balances(default_model, kkt):
    ds = run_case(with_interface(CaseSpec(), model="coulomb", friction=0.3), model=default_model)
    kkt(ds)
    assert int(ds.bolt_trials) >= 1 and not np.isnan(float(ds.bolt_theta))
    assert np.any(ds.slipping.values) and np.any(ds.shear_traction.values != 0)


def test_no_shear_where_the_gap_is_open(kkt):
    """Weightless unloaded ground, heavy lining resting on the invert with a 5 mm clearance."""
    spec = CaseSpec(geometry=dict(gap=0.005), ground=dict(density=0.0), loads=dict(surface_load=0.0),
                    lining=dict(density=2500.0), mesh=dict(far_size=8.0),
                    interface=dict(model="coulomb", friction=0.3))
    ds = run_case(spec)
    kkt(ds)
    gap, s, lam = ds.gap.values, ds.shear_traction.values, ds.contact_pressure.values
    u_ref = np.max(np.abs(ds.displacement_y.values))
    open_ = gap > 1e-6 * u_ref
    assert open_.sum() > 0.5 * open_.size and not open_[-1]  # resting on the invert
    assert np.all(s[open_] == 0) and np.all(lam[open_] == 0)
    assert np.any(s[~open_] != 0)


def test_coulomb_without_friction_is_rejected_naming_the_field():
    with pytest.raises(ValidationError) as err:
        CaseSpec.model_validate({"interface": {"model": "coulomb"}})
    assert [path for path, _ in field_errors(err.value)] == ["interface.friction"]


@pytest.mark.parametrize("cycles", ["first", "always"])
def test_cycle_guard_reaches_the_same_solution(cycles, default_model, monkeypatch):
    """Forcing the guard against cycling sets gives the active-set answer: once (Tresca steps,
    then the sets again) or always (the Tresca fixed point alone reaches the tolerance)."""
    spec = with_interface(CaseSpec(), model="coulomb", friction=0.3)
    d, F2 = contact_stage.forward_stage(default_model, spec)[2:]
    fp = friction.FrictionProblem(S=default_model.S, d=d, g0=0.0, w=default_model.w, r=default_model.r,
                                  F2=F2, m=default_model.m, mu=0.3)
    theta = default_model.mesh.interface.theta
    direct = friction.solve_coulomb(fp, theta, tol=1e-8, max_iterations=1000)
    calls = []
    inner = friction._active_set

    def cycling_first(*args, **kwargs):
        calls.append(1)
        if len(calls) == 1 or cycles == "always":
            t = np.zeros(fp.d.size)
            return t, args[4], 1, "cycle"
        return inner(*args, **kwargs)

    monkeypatch.setattr(friction, "_active_set", cycling_first)
    guarded = friction.solve_coulomb(fp, theta, tol=1e-8, max_iterations=1000)
    assert len(calls) >= 2
    J, _ = fp.jumps(guarded.t, guarded.bolt)
    assert friction.coulomb_kkt(fp, guarded.t, J, guarded.bolt) <= 0.5e-8
    np.testing.assert_allclose(guarded.t, direct.t, rtol=0, atol=1e-7 * np.max(np.abs(direct.t)))


def test_the_readme_interface_reading_reproduces(default_model):
    """README, the three interface models' reading: from μ ≈ 0.6 the shear the bond needs (at most
    0.49 λ, at θ ≈ 47°) is inside Coulomb's cone everywhere, so Coulomb equals the bond; and Einstein
    & Schwartz's cos 2θ moment amplitude for the default case (centreline radius 2.65 m) is 132 kN·m/m."""
    from solver.analytic import einstein_schwartz_slip_excavation

    coulomb = run_case(CaseSpec.model_validate({"interface": {"model": "coulomb", "friction": 0.6}}),
                       model=default_model)
    bonded = run_case(CaseSpec.model_validate({"interface": {"model": "bonded"}}), model=default_model)
    lam, shear = coulomb["contact_pressure"].values, np.abs(coulomb["shear_traction"].values)
    carrying = lam > 1e3
    ratio = shear[carrying] / lam[carrying]
    assert round(float(ratio.max()), 2) == 0.49 and abs(coulomb["theta"].values[carrying][ratio.argmax()] - 47) < 2
    assert not coulomb["slipping"].values.any()
    for name in ("max_thrust", "max_abs_moment", "max_contact_pressure"):
        assert float(coulomb[name]) == pytest.approx(float(bonded[name]), rel=1e-6), name
    sigma_v = 100e3 + 2000 * 9.81 * 15  # the surface load and the overburden at the axis
    M2, _, _ = einstein_schwartz_slip_excavation(0.7 * sigma_v, 0.5, 5e7, 0.3, 3e10, 0.2, 2.65, 0.3)
    assert round(abs(M2) / 1e3) == 132  # the amplitude (its sign: inner fibre in tension at the crown)
