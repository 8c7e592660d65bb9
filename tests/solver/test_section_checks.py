"""EN 1992-1-1 shear, crack width and the favourable-thrust N–M combination against hand
calculations (SPEC §9.3, issue 39). Every expected value is worked out here from the clauses,
independently of solver.lining.checks (MPa and mm where the code's formulas are in them)."""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from solver.lining.checks import crack_width, cracked_section, ecm, fctm, shear_utilization
from solver.lining.design import design_utilization, governing_thrust

H = 0.3  # section depth (m), b = 1 m


def design(**kw):
    values = dict(concrete_strength=30e6, steel_strength=500e6, reinforcement_area=1.5e-3, axis_distance=0.05,
                  load_factor=1.35, bar_diameter=0.014, crack_width_limit=0.3e-3)
    return SimpleNamespace(**(values | kw))


def test_material_values_table_3_1():
    # fctm = 0.30 fck^(2/3): 0.30 * 30^(2/3) = 0.30 * 9.6549 = 2.8965 MPa
    assert fctm(30e6) == pytest.approx(2.8965e6, rel=1e-4)
    # above C50/60: 2.12 ln(1 + fcm/10), C60: fcm = 68 -> 2.12 * ln 7.8 = 4.3549 MPa
    assert fctm(60e6) == pytest.approx(4.3549e6, rel=1e-4)
    # Ecm = 22 (fcm/10)^0.3 GPa, C30: 22 * 3.8^0.3 = 22 * 1.492587 = 32.837 GPa
    assert ecm(30e6) == pytest.approx(32.837e9, rel=1e-4)


# Reinforced (6.2.a/b), d = 0.25 m = 250 mm: k = 1 + sqrt(200/250) = 1.894427;
# rho_l = 1.5e-3 / 0.25 = 0.006; C_Rd,c = 0.18/1.5 = 0.12;
# 0.12 * 1.894427 * (100 * 0.006 * 30)^(1/3) = 0.2273313 * 2.6207414 = 0.5957763 MPa;
# v_min = 0.035 * 1.894427^1.5 * 30^0.5 = 0.035 * 2.6074 * 5.4772256 = 0.4998567 MPa -> 0.5957763 governs.
V_C = 0.5957763  # MPa


@pytest.mark.parametrize("N, V, sigma_cp", [
    # crown-like: N = 500 kN/m compression; thrusts 1.35 N = 675 and 1.0 N = 500: the lower one
    # gives the lower resistance, sigma_cp = 0.500 / 0.3 = 1.666667 MPa
    (500e3, 100e3, 0.500 / 0.3),
    # heavy thrust: 1.0 N = 1500 kN/m: 5.0 MPa > 0.2 fcd = 0.2 * 20 = 4.0 MPa, capped
    (1500e3, 150e3, 4.0),
    # tension: N = -100 kN/m, the worse thrust is 1.35 N = -135 kN/m: sigma_cp = -0.45 MPa
    (-100e3, 60e3, -0.135 / 0.3),
])
def test_shear_reinforced_three_stations(N, V, sigma_cp):
    v_rd = (V_C + 0.15 * sigma_cp) * 0.25 * 1e6          # N/m: (v + k1 sigma_cp) b d
    expected = 1.35 * V / v_rd
    got = shear_utilization(N, 40e3, V, H, design())
    assert got == pytest.approx(expected, rel=1e-6)


def test_shear_reinforced_sign_and_zero():
    d = design()
    eta = shear_utilization([500e3, 500e3, 500e3], [0.0, 0.0, 0.0], [-80e3, 80e3, 0.0], H, d)
    assert eta[0] == eta[1] > 0 and eta[2] == 0.0


# Plain (12.4)-(12.7), C30: fcd,pl = 0.8 * 30 / 1.5 = 16 MPa; fctk,0.05 = 0.7 * 2.896468 = 2.027528;
# fctd,pl = 0.8 * 2.027528 / 1.5 = 1.081348 MPa; sigma_c,lim = 16 - 2 sqrt(1.081348 * 17.081348)
# = 16 - 2 * 4.297798 = 7.404404 MPa.
FCTD, FCD_PL = 0.8 * 0.7 * 0.30 * 30 ** (2 / 3) / 1.5, 16.0


def plain_resistance(n_ed, m_ed):
    """V_Rd (MN/m) by hand: compressed depth of the no-tension elastic section, then (12.5)-(12.7)."""
    e = m_ed / n_ed
    x = H if e <= H / 6 else 3 * (H / 2 - e)
    sigma = n_ed / x                                                    # MPa (MN over m²)
    limit = FCD_PL - 2 * math.sqrt(FCTD * (FCTD + FCD_PL))
    fcvd2 = FCTD ** 2 + sigma * FCTD - (max(sigma - limit, 0) / 2) ** 2
    return math.sqrt(fcvd2) * x / 1.5


def test_plain_constants():
    assert FCTD == pytest.approx(1.081348, rel=1e-5)
    assert FCD_PL - 2 * math.sqrt(FCTD * (FCTD + FCD_PL)) == pytest.approx(7.404404, rel=1e-5)


@pytest.mark.parametrize("N, M, V, expected", [
    # N = 500, M = 30, V = 50 (kN): combinations (675, 40.5) and (500, 40.5):
    # (a) e = 0.06 > h/6 = 0.05: x = 3 (0.15 - 0.06) = 0.27, sigma = 2.5 MPa,
    #     fcvd = sqrt(1.169313 + 2.703370) = 1.967913, V_Rd = 1.967913 * 0.27 / 1.5 = 0.354224 MN
    # (b) e = 0.081: x = 0.207, sigma = 2.415459, fcvd = sqrt(1.169313 + 2.611952) = 1.944548,
    #     V_Rd = 0.268348 MN -> governs: eta = 1.35 * 0.050 / 0.268348 = 0.251539
    (500e3, 30e3, 50e3, 0.251539),
    # N = 3000, M = 0, V = 300: whole section compressed; (a) 4050: sigma 13.5 > 7.404404:
    #     fcvd² = 1.169313 + 14.598198 - (3.047798)² = 6.478505, V_Rd = 2.545291 * 0.3 / 1.5 = 0.509058
    # (b) 3000: sigma 10 > 7.404404: fcvd² = 1.169313 + 10.81348 - 1.297790² = 10.298534,
    #     V_Rd = 3.209133 * 0.2 = 0.641827; (a) governs: eta = 405 / 509.058 = 0.795587
    (3000e3, 0.0, 300e3, 0.795587),
])
def test_shear_plain_by_hand(N, M, V, expected):
    d = design(reinforcement_area=0.0)
    hand = 1.35 * V / 1e6 / min(plain_resistance(1.35 * N / 1e6, 1.35 * M / 1e6),
                                 plain_resistance(N / 1e6, 1.35 * M / 1e6))
    assert hand == pytest.approx(expected, rel=1e-5)
    assert shear_utilization(N, M, V, H, d) == pytest.approx(hand, rel=1e-9)


def test_shear_plain_tension_or_outside_the_section_is_inf():
    d = design(reinforcement_area=0.0)
    eta = shear_utilization([-10e3, 100e3, 100e3], [0.0, 20e3, 0.0], [1e3, 1e3, 0.0], H, d)
    # N < 0: no compressed area; e = 1.35 * 20 / 100 = 0.27 > h/2: none either; V = 0: 0
    assert np.isinf(eta[0]) and np.isinf(eta[1]) and eta[2] == 0.0


def test_crack_width_pure_bending_by_hand():
    """M = 100 kN·m/m, N = 0: cracked (6 M / h² = 6.667 MPa > fctm = 2.896 MPa). Neutral axis of the
    doubly reinforced elastic section from its quadratic, stress from the cracked inertia."""
    As, d1, h, phi = 1.5e-3, 0.05, H, 0.014
    d = h - d1
    alpha = 200e9 / (22e9 * 3.8 ** 0.3)                      # Es / Ecm = 200 / 32.8369 = 6.090771
    assert alpha == pytest.approx(6.090771, rel=1e-6)
    # b x²/2 + alpha As (x - d1) - alpha As (d - x) = 0  ->  x²/2 + 2 alpha As x - alpha As (d + d1) = 0
    a_, b_, c_ = 0.5, 2 * alpha * As, -alpha * As * (d + d1)
    x = (-b_ + math.sqrt(b_ ** 2 - 4 * a_ * c_)) / (2 * a_)
    assert x == pytest.approx(0.0579876, rel=1e-5)
    I_cr = x ** 3 / 3 + alpha * As * (x - d1) ** 2 + alpha * As * (d - x) ** 2      # about the neutral axis
    M = 100e3
    sigma_s = alpha * M * (d - x) / I_cr                       # Pa
    x_got, sigma_got = cracked_section(0.0, M, h, design())
    assert x_got == pytest.approx(x, rel=1e-9) and sigma_got == pytest.approx(sigma_s, rel=1e-9)
    fct = 0.30 * 30 ** (2 / 3) * 1e6
    hc = min(2.5 * (h - d), (h - x) / 3, h / 2)                # (0.3 - 0.0579876) / 3 = 0.0806708 < 0.125
    rho = As / hc                                              # 0.0185941
    strain = max((sigma_s - 0.4 * fct / rho * (1 + alpha * rho)) / 200e9, 0.6 * sigma_s / 200e9)
    s_r = 3.4 * (d1 - phi / 2) + 0.8 * 0.5 * 0.425 * phi / rho     # 0.1462 + 0.0023800 / 0.0185941 = 0.274198 m
    assert s_r == pytest.approx(0.274198, rel=1e-5)
    assert crack_width(0.0, M, h, design()) == pytest.approx(s_r * strain, rel=1e-9)
    assert crack_width(0.0, -M, h, design()) == pytest.approx(s_r * strain, rel=1e-9)   # symmetric section
    assert 0.2e-3 < s_r * strain < 0.5e-3


def test_cracked_section_balances_eccentric_thrust():
    """Under compression with bending the cracked elastic section's resultants are the applied forces."""
    d, h, d1, As = design(), H, 0.05, 1.5e-3
    alpha = 200e9 / ecm(30e6)
    for N, M in ((500e3, 141e3), (200e3, 80e3), (-50e3, 60e3)):
        x, sigma_s = cracked_section(N, M, h, d)
        ec_kappa = sigma_s / (alpha * (h - d1 - x))                # Ec κ
        xc = min(max(x, 0.0), h)
        n = ec_kappa * (x * xc - xc ** 2 / 2 + alpha * As * (2 * x - d1 - (h - d1)))
        m = ec_kappa * (h / 2 * x * xc - (x + h / 2) * xc ** 2 / 2 + xc ** 3 / 3
                        + alpha * As * ((x - d1) * (h / 2 - d1) - (x - h + d1) * (h / 2 - d1)))
        assert n == pytest.approx(N, rel=1e-8) and m == pytest.approx(M, rel=1e-8)


def test_crack_width_uncracked_zero_and_plain_inf():
    d = design()
    # 600 kN/m and 20 kN·m/m: -2.0 + 6 * 0.02 / 0.09 = -0.667 MPa: compression everywhere
    # 0 and 12 kN·m/m: 0.8 MPa < fctm: uncracked
    assert np.all(crack_width([600e3, 0.0], [20e3, 12e3], H, d) == 0.0)
    plain = design(reinforcement_area=0.0)
    w = crack_width([600e3, 100e3], [20e3, 50e3], H, plain)   # 100 kN, 50 kN·m: -0.333 + 3.333 > 2.9
    assert w[0] == 0.0 and np.isinf(w[1])


def test_bars_in_compression_under_a_cracked_face_give_no_crack_width():
    """A thrust so high that the neutral axis lies past the tension bars: the face still cracks
    (gross stress above fctm), the bars are compressed, and EN 1992's (7.8) at the bars gives no
    crack (w = 0), not a negative width. 3 MN/m and 130 kN·m/m on 0.2 m: -15 + 19.5 = 4.5 MPa > fctm;
    the neutral axis at 0.168 m, past the bars at d = 0.15 m."""
    d = design()
    x, sigma_s = cracked_section(3.0e6, 130e3, 0.2, d)
    assert x > 0.2 - d.axis_distance + 0.01 and sigma_s < 0    # the bars lie in the compressed zone
    assert crack_width(3.0e6, 130e3, 0.2, d) == 0.0
    assert crack_width([3.0e6, 0.0], [150e3, 60e3], 0.2, d)[1] > 0   # a tension face's bars: a crack


def test_favourable_thrust_governs_plain_section_by_hand():
    """Plain section, rectangular block (12.10): η = N_Ed / (fcd,pl b (h − 2e)), e = M_Ed / N_Ed
    (the ray meets N_Rd = fcd,pl b (h − 2e)). N = 500 kN/m:
    M = 40 kN·m/m: (675, 54): e = 0.08, η = 0.675 / (16 * 0.14) = 0.301339;
                   (500, 54): e = 0.108, η = 0.5 / (16 * 0.084) = 0.372024 -> the lower thrust governs;
    M = 10 kN·m/m: (675, 13.5): e = 0.02, η = 0.675 / (16 * 0.26) = 0.162260;
                   (500, 13.5): e = 0.027, η = 0.5 / (16 * 0.246) = 0.127033 -> γF N governs."""
    d = design(reinforcement_area=0.0)
    eta, _, _ = design_utilization([500e3, 500e3], [40e3, 10e3], H, d)
    np.testing.assert_allclose(eta, [0.372024, 0.162260], rtol=2e-3)   # polygon error < 0.1 %
    np.testing.assert_array_equal(governing_thrust([500e3, 500e3], [40e3, 10e3], H, d), [500e3, 675e3])


def test_reinforced_shear_constant_by_hand():
    k = 1 + math.sqrt(200 / 250)
    assert 0.12 * k * (100 * 0.006 * 30) ** (1 / 3) == pytest.approx(V_C, rel=1e-6)
    assert 0.035 * k ** 1.5 * 30 ** 0.5 == pytest.approx(0.4998567, rel=1e-6)
