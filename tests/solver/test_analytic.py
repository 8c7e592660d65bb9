"""Exact thick ring in an infinite medium (solver.analytic.exact_ring) against its own
field equations, boundary conditions, global equilibrium and the closed forms of
reference/closed-forms.md (θ from the crown: cos 2θ amplitudes are minus those from
the springline)."""
from __future__ import annotations

import numpy as np
import pytest

from solver.analytic import (_n0, _n2, einstein_schwartz_slip_excavation, exact_ring,
                             kirsch_wall_displacement, ring_pressure, thin_ring_cos2)

P, K = 1.0e5, 0.5
E, NU = 5.0e7, 0.3
E_L, NU_L = 3.0e10, 0.2
A, B = 2.5, 2.8
COMBOS = [(lo, it) for lo in ("external", "excavation") for it in ("slip", "bonded")]


def solve(loading, interface, **kw):
    args = dict(P=P, K=K, E=E, nu=NU, E_l=E_L, nu_l=NU_L, a=A, b=B) | kw
    return exact_ring(**args, loading=loading, interface=interface)


def far_field_polar(theta_deg, K=K):
    """Uniform field σxx = −K P, σyy = −P in polar components, θ from the crown
    (e_r = (sin θ, cos θ), e_θ = de_r/dθ = (cos θ, −sin θ))."""
    th = np.radians(theta_deg)
    sxx, syy = -K * P, -P
    s, c = np.sin(th), np.cos(th)
    return dict(sigma_rr=sxx * s**2 + syy * c**2, sigma_tt=sxx * c**2 + syy * s**2,
                sigma_rt=s * c * (sxx - syy))


def test_michell_table_is_the_sympy_derivation():
    """Stresses from the Airy function and plane-strain displacements integrated from
    the strains (b = 1, G = 1 so u = G u / b), against the module's table."""
    sp = pytest.importorskip("sympy")
    r, ph = sp.symbols("r phi", positive=True)
    nu = sp.Rational(3, 10)
    G = sp.Integer(1)
    Em = 2 * G * (1 + nu)
    terms0 = [sp.log(r), r**2]
    terms2 = [r**2, r**4, r**-2, sp.Integer(1)]
    pts = [0.6, 0.9, 1.0, 1.7, 4.0]

    def derive(Phi, n):
        srr = sp.diff(Phi, r) / r + sp.diff(Phi, ph, 2) / r**2
        stt = sp.diff(Phi, r, 2)
        srt = -sp.diff(sp.diff(Phi, ph) / r, r)
        err = (1 + nu) / Em * ((1 - nu) * srr - nu * stt)
        ett = (1 + nu) / Em * ((1 - nu) * stt - nu * srr)
        if n == 0:
            ur, ut = sp.simplify(r * ett), sp.Integer(0)
        else:
            f = sp.integrate(sp.simplify(err / sp.cos(2 * ph)), r)
            g = sp.simplify((r * sp.simplify(ett / sp.cos(2 * ph)) - f) / 2)
            ur, ut = f * sp.cos(2 * ph), g * sp.sin(2 * ph)
        # compatibility: all three strains come from (ur, ut)
        assert sp.simplify(sp.diff(ur, r) - err) == 0
        assert sp.simplify((ur + sp.diff(ut, ph)) / r - ett) == 0
        assert sp.simplify(sp.diff(ur, ph) / r + sp.diff(ut, r) - ut / r - srt / G) == 0
        # equilibrium
        assert sp.simplify(sp.diff(srr, r) + sp.diff(srt, ph) / r + (srr - stt) / r) == 0
        assert sp.simplify(sp.diff(srt, r) + sp.diff(stt, ph) / r + 2 * srt / r) == 0
        return srr, stt, srt, ur, ut

    for n, terms, table in ((0, terms0, _n0), (2, terms2, _n2)):
        for k, psi in enumerate(terms):
            Phi = psi * (sp.cos(2 * ph) if n == 2 else 1)
            srr, stt, srt, ur, ut = derive(Phi, n)
            for x in pts:
                tab = {key: v[k] for key, v in table(x, 0.3).items()}
                at_c = {ph: 0}           # cos 2φ amplitudes
                at_s = {ph: sp.pi / 4}   # sin 2φ amplitudes
                assert float(srr.subs(r, x).subs(at_c)) == pytest.approx(tab["srr"], abs=1e-12)
                assert float(stt.subs(r, x).subs(at_c)) == pytest.approx(tab["stt"], abs=1e-12)
                assert float(ur.subs(r, x).subs(at_c)) == pytest.approx(tab["gur"], abs=1e-12)
                assert float(psi.subs(r, x)) == pytest.approx(tab["psi"], abs=1e-12)
                assert float(sp.diff(psi, r).subs(r, x)) == pytest.approx(tab["dpsi"], abs=1e-12)
                if n == 2:
                    assert float(srt.subs(r, x).subs(at_s)) == pytest.approx(tab["srt"], abs=1e-12)
                    assert float(ut.subs(r, x).subs(at_s)) == pytest.approx(tab["gut"], abs=1e-12)


@pytest.mark.parametrize("loading,interface", COMBOS)
def test_boundary_interface_and_far_field_conditions(loading, interface):
    sol = solve(loading, interface)
    th = np.linspace(0.0, 180.0, 37)
    ring_a = sol.field(A, th, "ring")
    ring_b = sol.field(B, th, "ring")
    ground_b = sol.field(B, th, "ground")
    P_ref, u_ref = P, np.max(np.abs(ground_b["u_r"]))
    # free inner surface
    np.testing.assert_allclose(ring_a["sigma_rr"], 0, atol=1e-9 * P_ref)
    np.testing.assert_allclose(ring_a["sigma_rt"], 0, atol=1e-9 * P_ref)
    # interface r = b
    np.testing.assert_allclose(ring_b["sigma_rr"], ground_b["sigma_rr"], atol=1e-9 * P_ref)
    np.testing.assert_allclose(ring_b["u_r"], ground_b["u_r"], atol=1e-9 * u_ref)
    if interface == "slip":
        np.testing.assert_allclose(ring_b["sigma_rt"], 0, atol=1e-9 * P_ref)
        np.testing.assert_allclose(ground_b["sigma_rt"], 0, atol=1e-9 * P_ref)
        assert np.max(np.abs(ring_b["u_t"] - ground_b["u_t"])) > 1e-3 * u_ref  # it does slip
    else:
        np.testing.assert_allclose(ring_b["sigma_rt"], ground_b["sigma_rt"], atol=1e-9 * P_ref)
        np.testing.assert_allclose(ring_b["u_t"], ground_b["u_t"], atol=1e-9 * u_ref)
    # the far field (total stress in the ground)
    far = sol.field(1e4 * B, th, "ground")
    for key, val in far_field_polar(th).items():
        np.testing.assert_allclose(far[key], val, atol=1e-6 * P)
    # excavation: ground displacement measured from the pre-stressed state decays
    if loading == "excavation":
        assert np.max(np.abs(far["u_r"])) < 1e-3 * u_ref
    # the reported amplitudes are the fields
    at = sol.at(th)
    np.testing.assert_allclose(at["contact_pressure"], -ring_b["sigma_rr"], atol=1e-9 * P_ref)
    np.testing.assert_allclose(at["shear_traction"], ring_b["sigma_rt"], atol=1e-9 * P_ref)
    np.testing.assert_allclose(at["ground_ur"], ground_b["u_r"], atol=1e-12 * u_ref)
    np.testing.assert_allclose(at["ground_ut"], ground_b["u_t"], atol=1e-12 * u_ref)
    np.testing.assert_allclose(at["lining_ur_outer"], ring_b["u_r"], atol=1e-12 * u_ref)
    np.testing.assert_allclose(at["lining_ur_inner"], ring_a["u_r"], atol=1e-12 * u_ref)
    np.testing.assert_allclose(at["lining_ut_outer"], ring_b["u_t"], atol=1e-12 * u_ref)


@pytest.mark.parametrize("loading,interface", COMBOS)
@pytest.mark.parametrize("body,r", [("ring", 2.6), ("ground", 3.3)])
def test_fields_obey_hooke_and_equilibrium_in_crown_coordinates(loading, interface, body, r):
    """Finite differences of the reported fields (θ from the crown, e_θ = de_r/dθ):
    strains of (u_r, u_θ) = plane-strain compliance × stress (minus the initial stress
    for excavation loading), and the polar equilibrium equations."""
    sol = solve(loading, interface)
    Em, nu = (E_L, NU_L) if body == "ring" else (E, NU)
    G = Em / (2 * (1 + nu))
    th = 31.0
    h, hd = 1e-4 * r, 1e-3

    def f(rr, tt):
        out = sol.field(rr, tt, body)
        if body == "ground" and loading == "excavation":
            init = far_field_polar(tt)
            out = {k: v - init[k] if k in init else v for k, v in out.items()}
        return out

    c = f(r, th)
    d_r = {k: (f(r + h, th)[k] - f(r - h, th)[k]) / (2 * h) for k in c}
    d_t = {k: (f(r, th + hd)[k] - f(r, th - hd)[k]) / (2 * np.radians(hd)) for k in c}
    e_rr = d_r["u_r"]
    e_tt = (c["u_r"] + d_t["u_t"]) / r
    g_rt = d_t["u_r"] / r + d_r["u_t"] - c["u_t"] / r
    s_rr, s_tt, s_rt = c["sigma_rr"], c["sigma_tt"], c["sigma_rt"]
    strain = np.max(np.abs([e_rr, e_tt, g_rt]))
    tol = 1e-5 * strain  # central differences of nearly cancelling Michell terms
    assert e_rr == pytest.approx((1 + nu) / Em * ((1 - nu) * s_rr - nu * s_tt), abs=tol)
    assert e_tt == pytest.approx((1 + nu) / Em * ((1 - nu) * s_tt - nu * s_rr), abs=tol)
    assert g_rt == pytest.approx(s_rt / G, abs=tol)
    full = sol.field(r, th, body)  # equilibrium of the total stress
    fr = {k: (sol.field(r + h, th, body)[k] - sol.field(r - h, th, body)[k]) / (2 * h) for k in full}
    ft = {k: (sol.field(r, th + hd, body)[k] - sol.field(r, th - hd, body)[k]) / (2 * np.radians(hd))
          for k in full}
    scale = max(abs(full["sigma_rr"]), abs(full["sigma_tt"]), abs(full["sigma_rt"])) / r
    assert abs(fr["sigma_rr"] + ft["sigma_rt"] / r + (full["sigma_rr"] - full["sigma_tt"]) / r) < 1e-5 * scale
    assert abs(fr["sigma_rt"] + ft["sigma_tt"] / r + 2 * full["sigma_rt"] / r) < 1e-5 * scale


@pytest.mark.parametrize("loading,interface", COMBOS)
def test_section_forces_integrate_the_ring_stress_and_balance_the_quarter_ring(loading, interface):
    sol = solve(loading, interface)
    r_mid = 0.5 * (A + B)
    x, w = np.polynomial.legendre.leggauss(40)
    r = r_mid + 0.5 * (B - A) * x
    wr = 0.5 * (B - A) * w
    # N = −∫σθθ dr, M = ∫σθθ (r − r_mid) dr, V = ∫σrθ dr, by quadrature of the field
    for th in (0.0, 30.0, 90.0, 150.0):
        f = sol.field(r, th, "ring")
        at = sol.at(th)
        assert at["thrust"] == pytest.approx(-wr @ f["sigma_tt"], rel=1e-10)
        assert at["moment"] == pytest.approx(wr @ (f["sigma_tt"] * (r - r_mid)), rel=1e-9, abs=1e-9 * B * P)
        assert at["shear"] == pytest.approx(wr @ f["sigma_rt"], rel=1e-9, abs=1e-9 * P)
    # quarter ring 0 ≤ θ ≤ 90: contact traction −λ e_r + s e_θ on r = b, cut forces
    xq, wq = np.polynomial.legendre.leggauss(40)
    t = np.pi / 4 * (xq + 1)
    wt = np.pi / 4 * wq
    at = sol.at(np.degrees(t))
    er = np.array([np.sin(t), np.cos(t)])
    et = np.array([np.cos(t), -np.sin(t)])
    contact = (-at["contact_pressure"] * er + at["shear_traction"] * et) @ wt * B
    c0, c90 = sol.at(0.0), sol.at(90.0)
    e_r0, e_t0, e_r90, e_t90 = np.array([0, 1]), np.array([1, 0]), np.array([1, 0]), np.array([0, -1])
    cut0 = c0["thrust"] * e_t0 - c0["shear"] * e_r0       # invert side of the cut at θ = 0
    cut90 = -c90["thrust"] * e_t90 + c90["shear"] * e_r90  # crown side of the cut at θ = 90
    np.testing.assert_allclose(contact + cut0 + cut90, 0, atol=1e-10 * P * B)
    # moment about the axis: ∫ r σθθ dr = M − r_mid N at each cut
    torque = -B**2 * (at["shear_traction"] @ wt) \
        + (c0["moment"] - r_mid * c0["thrust"]) - (c90["moment"] - r_mid * c90["thrust"])
    assert abs(torque) < 1e-10 * P * B**2
    if interface == "slip":  # no shear: the thick ring's M2 = r_mid N2 exactly
        assert sol.M2 == pytest.approx(r_mid * sol.N2, rel=1e-10)
        assert sol.s2 == 0.0 or abs(sol.s2) < 1e-10 * P
    else:
        assert abs(sol.s2) > 0.05 * P
        assert abs(sol.M2 - r_mid * sol.N2) > 0.1 * abs(sol.M2)


@pytest.mark.parametrize("young_l", [3e10, 5e8])
def test_hydrostatic_mean_pressure_matches_closed_forms(young_l):
    lam_l = (1 + NU_L) * ((1 - 2 * NU_L) * B**2 + A**2) / (young_l * (B**2 - A**2))
    q_exc = P / (1 + E * lam_l / (1 + NU))
    q_ext = ring_pressure(P, E, NU, young_l, NU_L, A, B)
    for (loading, interface), q in zip(COMBOS, [q_ext, q_ext, q_exc, q_exc]):
        sol = solve(loading, interface, K=1.0, E_l=young_l)
        assert sol.p0 == pytest.approx(q, rel=1e-12)
        assert sol.N0 == pytest.approx(q * B, rel=1e-12)
        assert abs(sol.p2) < 1e-10 * P and abs(sol.M2) < 1e-10 * P * B**2
        # Lamé: inner fibre more compressed than the outer, so M0 > 0
        assert sol.M0 > 0
        # the lining moves in by λ_l q b
        assert sol.ur_lining_b0 == pytest.approx(-lam_l * q * B, rel=1e-10)


def test_mean_terms_do_not_depend_on_the_interface():
    for loading in ("external", "excavation"):
        s, b = solve(loading, "slip"), solve(loading, "bonded")
        for key in ("p0", "N0", "M0", "ur_ground0", "ur_lining_b0", "ur_lining_a0"):
            assert getattr(s, key) == pytest.approx(getattr(b, key), rel=1e-12)
        assert s.p2 != pytest.approx(b.p2, rel=0.1)


@pytest.mark.parametrize("interface", ["slip", "bonded"])
def test_soft_lining_leaves_the_kirsch_hole(interface):
    sol = solve("excavation", interface, E_l=1e-6 * E)
    th = np.linspace(0, 180, 19)
    u_k = kirsch_wall_displacement(P, K, E, NU, B, th)
    np.testing.assert_allclose(sol.at(th)["ground_ur"], u_k, rtol=0, atol=1e-4 * np.max(np.abs(u_k)))
    # Kirsch in the crown convention: the crown moves in more than the springline for K < 1
    assert u_k[0] < u_k[9] < 0
    G = E / (2 * (1 + NU))
    assert u_k[0] == pytest.approx(-(P * B / (4 * G)) * ((1 + K) + (1 - K) * (3 - 4 * NU)))


@pytest.mark.parametrize("young_l", [3e10, 3e12, 3e14])  # F from 1.7e5 down to 17
def test_thin_ring_slip_tends_to_einstein_schwartz(young_l):
    R = 2.65
    t = 0.005 * R
    a, b = R - t / 2, R + t / 2
    ext = solve("external", "slip", E_l=young_l, a=a, b=b)
    M2_s, p2_s = thin_ring_cos2(P, K, E, NU, young_l, NU_L, R, t)  # from the springline
    assert ext.M2 == pytest.approx(-M2_s, rel=0.01)
    assert ext.p2 == pytest.approx(-p2_s, rel=0.01)
    assert ext.M2 < 0 < ext.p2  # K < 1: inner fibre in tension at the crown, crown loaded more
    exc = solve("excavation", "slip", E_l=young_l, a=a, b=b)
    M2, N0, N2 = einstein_schwartz_slip_excavation(P, K, E, NU, young_l, NU_L, R, t)
    assert exc.M2 == pytest.approx(M2, rel=0.01)
    assert exc.N0 == pytest.approx(N0, rel=0.01)
    assert exc.N2 == pytest.approx(N2, rel=0.01)
    # the thick-ring error falls with t/R (about t/2R here: 0.25 %)
    assert abs(exc.M2 / M2 - 1) < 0.004 and abs(ext.M2 / M2_s + 1) < 0.004


def test_thick_ring_departs_from_thin_ring_by_about_t_over_2R():
    R, t = 2.65, 0.3
    exc = solve("excavation", "slip")
    M2, _, _ = einstein_schwartz_slip_excavation(P, K, E, NU, E_L, NU_L, R, t)
    err = exc.M2 / M2 - 1
    assert 0.2 * t / (2 * R) < abs(err) < 2 * t / (2 * R)


def test_rigid_ring_limits():
    """E_l → ∞: the ring does not move, so u_r(b) = 0 (and u_θ(b) = 0 bonded); the
    contact stresses are those of a rigid inclusion (hand-derived from the same Michell
    terms with u = 0 at r = b):
    excavation bonded: the initial traction, p0 = P(1+K)/2, p2 = s2 = P(1−K)/2;
    excavation slip: p2 = 3P(1−K)(3−4ν) / (2(5−6ν));
    external: p0 = (1+K)(1−ν)P; slip p2 = 6P(1−K)(1−ν)/(5−6ν) (the thin-ring form at
    C = F = 0); bonded p2 = s2 = 2P(1−K)(1−ν)/(3−4ν) (Goodier's (κ+1)/κ)."""
    big = 1e12 * E
    u_scale = P * B / (E / (2 * (1 + NU)))
    expect = {
        ("excavation", "bonded"): (P * (1 + K) / 2, P * (1 - K) / 2, P * (1 - K) / 2),
        ("excavation", "slip"): (P * (1 + K) / 2, 3 * P * (1 - K) * (3 - 4 * NU) / (2 * (5 - 6 * NU)), 0.0),
        ("external", "bonded"): ((1 + K) * (1 - NU) * P, 2 * P * (1 - K) * (1 - NU) / (3 - 4 * NU),
                                 2 * P * (1 - K) * (1 - NU) / (3 - 4 * NU)),
        ("external", "slip"): ((1 + K) * (1 - NU) * P, 6 * P * (1 - K) * (1 - NU) / (5 - 6 * NU), 0.0),
    }
    for (loading, interface), (p0, p2, s2) in expect.items():
        sol = solve(loading, interface, E_l=big)
        assert abs(sol.ur_ground0) < 1e-6 * u_scale and abs(sol.ur_ground2) < 1e-6 * u_scale
        if interface == "bonded":
            assert abs(sol.ut_ground2) < 1e-6 * u_scale
        else:
            assert abs(sol.ut_ground2) > 1e-3 * u_scale
        assert sol.p0 == pytest.approx(p0, rel=1e-6)
        assert sol.p2 == pytest.approx(p2, rel=1e-6)
        assert sol.s2 == pytest.approx(s2, rel=1e-6, abs=1e-9 * P)


def test_bonded_reduces_the_moment_and_pressure_variation():
    for loading in ("external", "excavation"):
        s, b = solve(loading, "slip"), solve(loading, "bonded")
        assert abs(b.M2) < abs(s.M2) and abs(b.p2) < abs(s.p2)
        assert b.s2 > 0  # K < 1: the ground drags the lining from the crown towards the springline


def test_rejects_unknown_options_and_is_fast():
    with pytest.raises(ValueError):
        solve("deconfinement", "slip")
    with pytest.raises(ValueError):
        solve("external", "coulomb")
    import time
    t0 = time.perf_counter()
    for _ in range(20):
        solve("excavation", "bonded")
    assert (time.perf_counter() - t0) / 20 < 0.05
