"""Generalized Hoek–Brown ground (SPEC §9.1): the constants, the return mapping (on the surface, Koiter's
multipliers, a = 1 against Mohr–Coulomb), its consistent tangent against finite differences (and the
Mohr–Coulomb one's), and the hole in Hoek–Brown ground against Salençon (a = 1), Carranza-Torres &
Fairhurst (a = ½) and its own equilibrium, criterion, continuity and flow rule."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import nnls

from solver.ground import mohr_coulomb as mc
from solver.analytic import salencon
from solver.ground.hoek_brown import (HBMaterial, constants, consistent_tangent, default_tensile_strength,
                               hoek_brown_excess, parameter_errors, return_map, return_stress, yield_values)
from solver.ground.hoek_brown_hole import critical_pressure, ground_reaction_curve, hoek_brown_hole, plastic_radius
from solver.ground.tangent import elastic_matrix

E, NU = 5.0e9, 0.25
LAM, MU = E * NU / ((1 + NU) * (1 - 2 * NU)), E / (2 * (1 + NU))
UCS, GSI, MI = 5.0e7, 50.0, 10.0
SCALE = 2.0e7  # of the random trial stresses


def _trials(n, seed, scale=SCALE):
    rng = np.random.default_rng(seed)
    return rng.normal(0, scale, (4, n)) - np.array([0.5, 0.5, 0, 0.5])[:, None] * scale


def _sorted_principal(stress):
    major, minor, _, zz = mc.principal(stress)
    return np.sort(np.stack([major, minor, zz]), axis=0)[::-1]


# --- constants and inputs -------------------------------------------------------------------------------


def test_constants_against_hand_values():
    mb, s, a = constants(100.0, 12.0, 0.0)  # intact rock: m_b = m_i, s = 1, a = ½
    assert mb == pytest.approx(12.0, rel=1e-15) and s == pytest.approx(1.0, rel=1e-15)
    assert a == pytest.approx(0.5, abs=1e-15)
    # GSI 50, m_i 10, D 0 (Hoek et al. 2002's table: 1.6768, 0.0039, 0.506) and D = 1
    np.testing.assert_allclose(constants(50.0, 10.0, 0.0), (1.676772, 3.865920e-3, 0.5057336), rtol=1e-6)
    np.testing.assert_allclose(constants(50.0, 10.0, 1.0), (0.2811566, 2.403695e-4, 0.5057336), rtol=1e-6)
    # a rises towards ⅔ as GSI falls
    assert constants(10.0, 10.0, 0.0)[2] == pytest.approx(0.5 + (np.exp(-10 / 15) - np.exp(-20 / 3)) / 6, rel=1e-15)
    assert default_tensile_strength(UCS, 50.0, 10.0, 0.0) == pytest.approx(5e7 * 3.865920e-3 / 1.676772, rel=1e-6)


@pytest.mark.parametrize("fields, bad", [
    (dict(ucs=0.0), "ucs"), (dict(ucs=float("nan")), "ucs"), (dict(ucs=float("inf")), "ucs"),
    (dict(gsi=9.0), "gsi"), (dict(gsi=101.0), "gsi"), (dict(mi=0.5), "mi"), (dict(mi=51.0), "mi"),
    (dict(disturbance=-0.1), "disturbance"), (dict(disturbance=1.5), "disturbance"),
    (dict(dilatancy=-1.0), "dilatancy"), (dict(tensile_strength=-1.0), "tensile_strength"),
    (dict(tensile_strength=1e6), "tensile_strength")])  # above the apex s σci / m_b ≈ 115 kPa
def test_parameter_errors_name_the_field(fields, bad):
    good = dict(ucs=UCS, gsi=GSI, mi=MI, disturbance=0.0)
    assert parameter_errors(**good) == {}
    assert parameter_errors(**good, tensile_strength=1e5) == {}
    assert list(parameter_errors(**{**good, **fields})) == [bad]


def test_hoek_brown_excess_of_a_geostatic_state():
    mb, s, a = (float(v) for v in constants(GSI, MI, 0.0))
    minor = 2e6
    major = minor + UCS * (mb * minor / UCS + s) ** a  # on the surface
    assert hoek_brown_excess(major, minor, UCS, GSI, MI, 0.0) == pytest.approx(0.0, abs=1e-8 * major)
    assert hoek_brown_excess(major * 0.9, minor, UCS, GSI, MI, 0.0) < 0 < hoek_brown_excess(major * 1.1, minor, UCS,
                                                                                             GSI, MI, 0.0)
    assert hoek_brown_excess(0.0, -2e4, UCS, GSI, MI, 0.0, tensile_strength=1e4) == pytest.approx(1e4)


# --- the return -----------------------------------------------------------------------------------------


@pytest.mark.parametrize("psi, tensile", [(0.0, None), (0.0, 0.0), (30.0, None), (30.0, 5e4), (10.0, 0.0)])
def test_returned_stresses_lie_on_the_surface_and_follow_the_flow_rule(psi, tensile):
    n = 4000
    trial = _trials(n, 7)
    mat = HBMaterial.of(n, LAM, MU, UCS, GSI, MI, 0.0, psi, tensile)
    stress, dep, at_yield = return_stress(trial, mat)
    s = _sorted_principal(stress)
    f = yield_values(s, mat)
    assert f.max() <= 1e-9 * SCALE  # every returned state on or inside every surface
    f_trial = yield_values(_sorted_principal(trial), mat).max(axis=0)
    elastic = f_trial <= 0
    np.testing.assert_array_equal(stress[:, elastic], trial[:, elastic])  # elastic states untouched
    assert np.abs(f.max(axis=0)[~elastic]).max() <= 1e-9 * SCALE  # plastic ones on the surface
    assert at_yield[~elastic].all() and 0.3 < (~elastic).mean() < 1
    # trial - stress = D Δεp in the trial's principal axes
    ta, ti, _, tz = mc.principal(trial)
    sa, si, _, sz = mc.principal(stress)
    drop = np.stack([ta - sa, ti - si, tz - sz])
    np.testing.assert_allclose(drop, LAM * dep.sum(axis=0) + 2 * MU * dep, rtol=0, atol=1e-9 * SCALE)
    if psi == 0 and tensile is None:  # no volume change off the cut-off's corner
        off = s[0, ~elastic] < mat.tensile[0] - 1.0
        assert np.abs(dep.sum(axis=0)[~elastic][off]).max() <= 1e-12


@pytest.mark.parametrize("psi, tensile", [(0.0, None), (30.0, 0.0), (10.0, 5e4)])
def test_koiter_multipliers_are_non_negative_on_the_active_surfaces(psi, tensile):
    """The plastic strain is a non-negative combination of the flow directions of the surfaces the
    returned stress lies on (non-negative least squares leaves no residual)."""
    n = 1500
    trial = _trials(n, 11)
    mat = HBMaterial.of(n, LAM, MU, UCS, GSI, MI, 0.0, psi, tensile)
    stress, dep, _ = return_stress(trial, mat)
    major, minor, _, zz = mc.principal(trial)
    order = np.argsort(-np.stack([major, minor, zz]), axis=0, kind="stable")
    ds = np.take_along_axis(dep, order, axis=0)  # in the trial's sorted axes
    ta, tb, (c2, s2), _ = mc.principal(trial)
    cc, ss, sc = 0.5 * (1 + c2), 0.5 * (1 - c2), 0.5 * s2  # cos², sin², sin cos of the major direction
    ret = np.stack([stress[0] * cc + stress[1] * ss + 2 * stress[2] * sc,
                    stress[0] * ss + stress[1] * cc - 2 * stress[2] * sc, stress[3]])
    ret = np.take_along_axis(ret, order, axis=0)
    fv = yield_values(ret, mat)
    sq = np.sin(np.radians(psi))
    flows = np.array([[1 + sq, 0, -(1 - sq)], [0, 1 + sq, -(1 - sq)], [1 + sq, -(1 - sq), 0], *np.eye(3)])
    plastic = np.flatnonzero(np.any(dep != 0, axis=0))
    assert plastic.size > 500
    for i in plastic:
        active = fv[:, i] >= -1e-7 * SCALE  # (x^a at the apex: σci (1e-17)^½ ≈ 0.2 Pa)
        assert active.any()
        gam, resid = nnls(flows[active].T, ds[:, i])
        assert resid <= 1e-9 * np.abs(ds[:, i]).max()


@pytest.mark.parametrize("gsi, mi, D, psi, nu", [(10, 1, 1, 0, 0.0), (10, 50, 0, 45, 0.49), (100, 50, 1, 0, 0.3),
                                                   (100, 1, 0, 45, 0.0), (30, 25, 0.5, 20, 0.2)])
@pytest.mark.parametrize("scale", [1e5, 1e7])
def test_the_return_holds_across_the_admissible_inputs(gsi, mi, D, psi, nu, scale):
    n = 2000
    lam, mu = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
    trial = _trials(n, 13, scale=scale)
    mat = HBMaterial.of(n, lam, mu, UCS, gsi, mi, D, psi)
    stress, _, _, C = consistent_tangent(trial, mat)
    assert yield_values(_sorted_principal(stress), mat).max() <= 1e-9 * scale
    assert np.isfinite(C).all()


def test_hydrostatic_tension_returns_to_the_cut_off():
    mb, s, _ = constants(GSI, MI, 0.0)
    apex = s * UCS / mb
    trial = mc.from_principal(np.full(3, 5e6), np.full(3, 5e6), (np.ones(3), np.zeros(3)), np.full(3, 5e6))
    for t in (None, 0.5 * apex, 0.0):
        stress, dep, _ = return_map(trial, LAM, MU, UCS, GSI, MI, 0.0, 10.0, t)
        expected = apex if t is None else t
        np.testing.assert_allclose(stress[[0, 1, 3]], expected, rtol=1e-12, atol=1e-6)
        np.testing.assert_allclose(stress[2], 0.0, atol=1e-6)
        assert np.all(dep > 0)


def _mc_equivalent(mb, s, ucs):
    """Mohr–Coulomb's c, φ of Hoek–Brown with a = 1: σ1 = (1 + m_b) σ3 + s σci (compression positive),
    Kp = 1 + m_b, σc = s σci: sin φ = m_b / (2 + m_b), c = σc (1 - sin φ) / (2 cos φ)."""
    sp = mb / (2 + mb)
    phi = np.degrees(np.arcsin(sp))
    return s * ucs * (1 - sp) / (2 * np.cos(np.radians(phi))), phi


@pytest.mark.parametrize("psi, tensile_fraction", [(0.0, 1.0), (20.0, 0.0), (10.0, 0.5)])
def test_a_equal_one_is_mohr_coulomb(psi, tensile_fraction):
    n = 4000
    mb, s = 1.6, 4e-3
    c, phi = _mc_equivalent(mb, s, UCS)
    apex = s * UCS / mb
    assert apex == pytest.approx(c / np.tan(np.radians(phi)), rel=1e-12)  # the same apex
    t = tensile_fraction * apex
    one = lambda v: np.full(n, float(v))  # noqa: E731
    hb = HBMaterial(one(LAM), one(MU), one(UCS), one(mb), one(s), one(1.0), one(np.sin(np.radians(psi))), one(t))
    trial = _trials(n, 3, scale=1e6)
    stress, dep, flags = return_stress(trial, hb)
    ref, ref_dep, ref_flags = mc.return_map(trial, LAM, MU, c, phi, psi, t)
    assert 0.3 < np.any(dep != 0, axis=0).mean() < 1
    np.testing.assert_allclose(stress, ref, rtol=0, atol=1e-9 * 1e6)
    np.testing.assert_allclose(dep, ref_dep, rtol=0, atol=1e-9 * 1e6 / E)
    np.testing.assert_array_equal(flags, ref_flags)


def test_the_main_surface_return_converges_to_machine_precision():
    """The Newton return of one point: the stress on the curved surface to 1e-12 relative."""
    mat = HBMaterial.of(1, LAM, MU, UCS, 20.0, 15.0, 0.5, 5.0)
    trial = mc.from_principal(np.array([-1e6]), np.array([-3e7]), (np.cos([0.6]), np.sin([0.6])),  # θ 0.3
                              np.array([-1.2e7]))
    stress, _, _ = return_stress(trial, mat)
    s = _sorted_principal(stress)
    assert abs(yield_values(s, mat)[0, 0]) <= 1e-12 * 3e7
    assert s[0, 0] > s[1, 0] > s[2, 0]  # on the main surface, not an edge


# --- consistent tangents against central differences ----------------------------------------------------


def _classify(stress, tensile, scale):
    """0 main surface, 1 right edge (σ1 = σ2), 2 left edge (σ2 = σ3), 3 cut-off (σ1 = σt, corners)."""
    s = _sorted_principal(stress)
    gap = 1e-9 * np.maximum(np.abs(s).max(axis=0), scale)
    cls = np.zeros(stress.shape[1], int)
    cls[s[0] - s[1] <= gap] = 1
    cls[s[1] - s[2] <= gap] = 2
    cls[s[0] >= tensile - gap] = 3
    return cls


def _fd_errors(trial, ret, tangent, lam, mu, h_stress):
    """Central differences of the return along each strain component, against ``tangent``: the largest
    error per point relative to the elastic stiffness, and the classes of the perturbed returns."""
    D = elastic_matrix(lam, mu)[0]
    h = h_stress / np.abs(D).max()
    fd = np.zeros_like(tangent)
    same = np.ones(trial.shape[1], bool)
    for k in range(4):
        d = (D[:, k] * h)[:, None]
        plus, minus = ret(trial + d), ret(trial - d)
        fd[:, :, k] = (plus - minus).T / (2 * h)
        yield_change = (np.any(plus != trial + d, axis=0) != np.any(minus != trial - d, axis=0))
        same &= ~yield_change
    return np.abs(fd - tangent).max(axis=(1, 2)) / np.abs(D).max(), same


@pytest.mark.parametrize("psi, tensile", [(0.0, None), (0.0, 0.0), (30.0, None), (30.0, 2e4)])
def test_hoek_brown_tangent_matches_central_differences(psi, tensile):
    n = 3000
    trial = _trials(n, 5)
    mat = HBMaterial.of(n, LAM, MU, UCS, GSI, MI, 0.0, psi, tensile)
    stress, _, _, C = consistent_tangent(trial, mat)
    np.testing.assert_array_equal(stress, return_stress(trial, mat)[0])
    err, same = _fd_errors(trial, lambda t: return_stress(t, mat)[0], C, LAM, MU, 1e-6 * SCALE)
    cls = _classify(stress, mat.tensile[0], SCALE)
    plastic = np.any(stress != trial, axis=0)
    for k in range(4):  # main surface, both edges, cut-off: each met and each right
        where = plastic & same & (cls == k)
        assert where.sum() >= 10, k
        assert err[where].max() <= 1e-6, (k, err[where].max())
    elastic = ~plastic & same
    np.testing.assert_allclose(C[elastic], np.broadcast_to(elastic_matrix(LAM, MU)[0], C[elastic].shape))
    # relative to the tangent itself off the corners (where it is of the stiffness's order)
    main = plastic & same & (cls < 3)
    assert (err[main] * np.abs(elastic_matrix(LAM, MU)).max() / np.abs(C[main]).max(axis=(1, 2))).max() <= 1e-6


@pytest.mark.parametrize("c, phi, psi, t", [(2e4, 30, 0, 0), (2e4, 30, 30, 0), (1e4, 25, 10, 5e3),
                                             (1e4, 35, 35, 1e4 / np.tan(np.radians(35)))])
def test_mohr_coulomb_tangent_matches_central_differences(c, phi, psi, t):
    n = 3000
    e, nu = 5.0e7, 0.3
    lam, mu = e * nu / ((1 + nu) * (1 - 2 * nu)), e / (2 * (1 + nu))
    trial = _trials(n, 9, scale=2e5)
    mat = mc.Material.of(n, lam, mu, c, phi, psi, t)
    stress, _, _, returned, C_returned = mc.consistent_tangent(trial, mat)
    C = np.repeat(elastic_matrix(lam, mu), n, axis=0) if np.ndim(lam) == 0 else elastic_matrix(lam, mu)
    C[returned] = C_returned
    err, same = _fd_errors(trial, lambda x: mc.return_stress(x, mat)[0], C, lam, mu, 1e-6 * 2e5)
    cls = _classify(stress, t, 2e5)
    plastic = np.any(stress != trial, axis=0)
    for k in range(4):
        where = plastic & same & (cls == k)
        assert where.sum() >= 5, k
        assert err[where].max() <= 1e-6, (k, err[where].max())


# --- the hole -------------------------------------------------------------------------------------------


@pytest.mark.parametrize("p, psi", [(0.0, 0.0), (0.0, 20.0), (1e5, 10.0), (6e5, 10.0)])
def test_hole_with_a_equal_one_is_salencon(p, psi):
    P0, E_, nu, a = 1e6, 5e8, 0.3, 2.5
    c, phi = 5e4, 30.0
    sp = np.sin(np.radians(phi))
    Kp, sc = (1 + sp) / (1 - sp), 2 * c * np.cos(np.radians(phi)) / (1 - sp)
    ucs = 2e6
    hb = hoek_brown_hole(P0, ucs, 0, 0, 0, psi, E_, nu, a, p, hb=(Kp - 1, sc / ucs, 1.0))
    ref = salencon(P0, c, phi, psi, E_, nu, a, p, n=200001)
    for key in ("p_cr", "R0", "u_wall"):
        assert hb[key] == pytest.approx(ref[key], rel=1e-6), key
    assert (hb["R0"] > a) == (p < ref["p_cr"])
    r = np.linspace(a, 3 * hb["R0"], 40)
    np.testing.assert_allclose(hb["sigma_r"](r), ref["sigma_r"](r), rtol=1e-6, atol=1e-6 * P0)
    np.testing.assert_allclose(hb["sigma_theta"](r), ref["sigma_theta"](r), rtol=1e-6, atol=1e-6 * P0)


@pytest.mark.parametrize("P0, p", [(2e7, 0.0), (2e7, 2e6), (5e6, 0.0)])
def test_hole_with_a_half_is_carranza_torres_and_fairhurst(P0, p):
    """a = ½ in the scaled stresses S = σ/(m_b σci) + s/m_b² (Carranza-Torres & Fairhurst 1999):
    S_cr = (1 - √(1 + 16 S0))² / 16 and R0 = a exp(2(√S_cr - √S_p))."""
    ucs, mb, s, a = 3e7, 2.0, 4e-3, 3.0
    scaled = lambda v: v / (mb * ucs) + s / mb**2  # noqa: E731
    S_cr = (1 - np.sqrt(1 + 16 * scaled(P0))) ** 2 / 16
    p_cr = (S_cr - s / mb**2) * mb * ucs
    hole = hoek_brown_hole(P0, ucs, 0, 0, 0, 5.0, 5e9, 0.25, a, p, hb=(mb, s, 0.5))
    assert hole["p_cr"] == pytest.approx(p_cr, rel=1e-12)
    assert hole["R0"] == pytest.approx(a * np.exp(2 * (np.sqrt(S_cr) - np.sqrt(scaled(p)))), rel=1e-9)


@pytest.mark.parametrize("gsi, D, psi, p", [(40.0, 0.0, 5.0, 1e6), (20.0, 0.5, 0.0, 0.0), (70.0, 0.0, 15.0, 0.0)])
def test_hole_stresses_and_displacement_are_self_consistent(gsi, D, psi, p):
    P0, ucs, mi, E_, nu, a = 2e7, 5e7, 10.0, 5e9, 0.25, 3.0
    mb, s, a_hb = (float(v) for v in constants(gsi, mi, D))
    hole = hoek_brown_hole(P0, ucs, gsi, mi, D, psi, E_, nu, a, p)
    R0 = hole["R0"]
    assert R0 > a and R0 == pytest.approx(plastic_radius(P0, ucs, mb, s, a_hb, a, p), rel=1e-9)
    assert hole["sigma_r"](a) == pytest.approx(p, abs=1e-9 * P0)
    # the elastic ground yields at its wall at p_cr: 2 (P0 - p_cr) = σci (m_b p_cr/σci + s)^a
    p_cr = hole["p_cr"]
    assert 2 * (P0 - p_cr) == pytest.approx(ucs * (mb * p_cr / ucs + s) ** a_hb, rel=1e-12)
    # equilibrium and the criterion in the plastic zone
    r = np.linspace(a * 1.001, R0 * 0.999, 200)
    h = 1e-6 * R0
    d_sr = (hole["sigma_r"](r + h) - hole["sigma_r"](r - h)) / (2 * h)
    sr, st = hole["sigma_r"](r), hole["sigma_theta"](r)
    np.testing.assert_allclose(d_sr, (st - sr) / r, rtol=1e-6)
    np.testing.assert_allclose(st - sr, ucs * (mb * sr / ucs + s) ** a_hb, rtol=1e-12)
    # continuity at R0 of σr, σθ and u; the elastic zone inside the criterion
    for f in ("sigma_r", "sigma_theta", "u"):
        inside, outside = hole[f](R0 * (1 - 1e-9)), hole[f](R0 * (1 + 1e-9))
        assert inside == pytest.approx(outside, rel=1e-6), f
    ro = np.linspace(R0 * 1.01, 5 * R0, 50)
    assert np.all(hole["sigma_theta"](ro) - hole["sigma_r"](ro) <= ucs * (mb * hole["sigma_r"](ro) / ucs + s) ** a_hb)
    # the flow rule: ε_r^p + Kψ ε_θ^p = 0 with ε = (du/dr, u/r) (u outward) minus the elastic strains
    G = E_ / (2 * (1 + nu))
    Kq = (1 + np.sin(np.radians(psi))) / (1 - np.sin(np.radians(psi)))
    w = lambda x: -hole["u"](x)  # noqa: E731  (outward)
    e_r, e_t = (w(r + h) - w(r - h)) / (2 * h), w(r) / r
    dr_, dt_ = sr - P0, st - P0
    ee_r = -(1 + nu) / E_ * ((1 - nu) * dr_ - nu * dt_)
    ee_t = -(1 + nu) / E_ * ((1 - nu) * dt_ - nu * dr_)
    np.testing.assert_allclose((e_r - ee_r) + Kq * (e_t - ee_t), 0.0, atol=1e-6 * abs(e_t).max())
    # at the edge of the plastic zone, the elastic ground's wall displacement of p_cr
    assert hole["u"](R0) == pytest.approx((P0 - p_cr) * R0 / (2 * G), rel=1e-9)


def test_hole_elastic_when_the_ground_holds():
    P0, ucs, E_, nu, a = 1e6, 5e7, 5e9, 0.25, 3.0
    hole = hoek_brown_hole(P0, ucs, 60.0, 12.0, 0.0, 0.0, E_, nu, a, 0.0)
    assert hole["R0"] == a and hole["p_cr"] < 0
    assert hole["u_wall"] == pytest.approx(P0 * a * (1 + nu) / E_, rel=1e-12)  # Lamé: P0 a / 2G


def test_ground_reaction_curve_falls_from_p0_to_the_unsupported_wall():
    args = (2e7, 5e7, 40.0, 10.0, 0.0, 5.0, 5e9, 0.25, 3.0)
    grc = ground_reaction_curve(*args, n=21)
    assert grc["p"][0] == 2e7 and grc["p"][-1] == 0.0 and grc["u_wall"][0] == 0.0
    assert np.all(np.diff(grc["u_wall"]) > 0) and np.all(np.diff(grc["R0"]) >= 0)
    assert grc["u_wall"][-1] == pytest.approx(hoek_brown_hole(*args, 0.0)["u_wall"], rel=1e-12)
    p_cr = critical_pressure(2e7, 5e7, *(float(v) for v in constants(40.0, 10.0, 0.0)))
    elastic = grc["p"] >= p_cr
    G = 5e9 / 2.5
    np.testing.assert_allclose(grc["u_wall"][elastic], (2e7 - grc["p"][elastic]) * 3.0 / (2 * G), rtol=1e-12)


def test_return_map_takes_the_spec_fields():
    trial = _trials(200, 1)
    mat = HBMaterial.of(200, LAM, MU, UCS, GSI, MI, 0.2, 5.0)
    for got, ref in zip(return_map(trial, LAM, MU, UCS, GSI, MI, 0.2, 5.0), return_stress(trial, mat)):
        np.testing.assert_array_equal(got, ref)
