"""A circular tunnel in generalized Hoek–Brown ground (Carranza-Torres & Fairhurst 1999; Carranza-Torres
2004): the hole of radius ``a`` under the hydrostatic far field P0 and the support pressure p, plane
strain, elastic–perfectly plastic with a constant dilatancy ψ (plastic potential of Mohr–Coulomb type,
as :mod:`solver.ground.hoek_brown`). Compression positive, as :func:`solver.analytic.salencon`.

In the plastic zone a ≤ r ≤ R0 the radial stress is the minor principal stress and the hoop stress the
major one, σθ = σr + σci q(σr)^a with q(σ) = m_b σ/σci + s; equilibrium ``dσr/dr = (σθ - σr)/r`` is
integrated outwards from σr(a) = p to the radius R0 where σr reaches the critical pressure p_cr, that of
the elastic ground's yield at its wall: 2 (P0 - p_cr) = σci q(p_cr)^a. With σz the intermediate stress
the flow rule gives ε_r^p + Kψ ε_θ^p = 0 (Kψ = (1 + sin ψ)/(1 - sin ψ)); the elastic strains in the
plastic zone are those of the stress change from P0, so compatibility reads
``d(w r^Kψ)/dr = (ε_r^e + Kψ ε_θ^e) r^Kψ`` (w outward, strains tension positive), integrated along
with σr, from w(R0) = -(P0 - p_cr) R0 / 2G of the elastic ground outside.
"""
from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from .hoek_brown import constants as hb_constants

#: Relative tolerance of the integration (solve_ivp, DOP853).
RTOL = 1e-12


def critical_pressure(P0: float, ucs: float, mb: float, s: float, a_hb: float) -> float:
    """The support pressure p_cr (Pa, compression positive) below which the wall yields:
    2 (P0 - p_cr) = σci (m_b p_cr/σci + s)^a (the left side falls, the right one rises in p_cr)."""
    def excess(pc):
        return 2.0 * (P0 - pc) - ucs * max(mb * pc / ucs + s, 0.0) ** a_hb
    low = -s * ucs / mb
    if excess(P0) >= 0.0:  # P0 at or below the biaxial tensile strength: nothing to yield
        return P0
    return brentq(excess, low, P0, xtol=1e-14 * max(abs(P0), ucs), rtol=4 * np.finfo(float).eps, maxiter=500)


def plastic_radius(P0: float, ucs: float, mb: float, s: float, a_hb: float, a: float, p: float) -> float:
    """The plastic radius R0 (m) in closed form (the integral of equilibrium, for a check):
    ln(R0/a) = [q(p_cr)^(1-a) - q(p)^(1-a)] / ((1-a) m_b), or ln(q(p_cr)/q(p)) / m_b at a = 1."""
    p_cr = critical_pressure(P0, ucs, mb, s, a_hb)
    if p >= p_cr:
        return a
    qc, qp = mb * p_cr / ucs + s, mb * p / ucs + s
    if abs(1.0 - a_hb) < 1e-12:
        return a * (qc / qp) ** (1.0 / mb)
    return a * np.exp((qc ** (1.0 - a_hb) - qp ** (1.0 - a_hb)) / ((1.0 - a_hb) * mb))


def hoek_brown_hole(P0: float, ucs: float, gsi: float, mi: float, disturbance: float, psi: float, E: float,
                    nu: float, a: float, p: float = 0.0, *, hb: tuple[float, float, float] | None = None) -> dict:
    """The hole of radius ``a`` (m) in Hoek–Brown ground under ``P0``, supported by ``p`` (Pa, compression
    positive; σci = ``ucs``, ``gsi``, ``mi``, ``disturbance`` D, dilatancy ``psi`` in degrees, Young's
    ``E``, Poisson's ``nu``). ``hb = (m_b, s, a)`` overrides the constants (tests: a = 1 is
    Mohr–Coulomb). The support must keep the wall above the criterion's tensile apex (p > -s σci/m_b).

    Returns, as :func:`solver.analytic.salencon`: ``R0`` (m), ``u_wall`` (m, inward), ``p_cr`` (Pa),
    ``sigma_r(r)``, ``sigma_theta(r)`` (Pa, compression positive, a ≤ r) and, beside them, ``u(r)``
    (m, inward displacement, a ≤ r).
    """
    mb, s, a_hb = hb if hb is not None else (float(v) for v in hb_constants(gsi, mi, disturbance))
    G = E / (2.0 * (1.0 + nu))
    sq = np.sin(np.radians(psi))
    Kq = (1.0 + sq) / (1.0 - sq)
    p_cr = critical_pressure(P0, ucs, mb, s, a_hb)

    def elastic(R, pR):
        def sigma_r(r):
            return P0 - (P0 - pR) * (R / np.asarray(r, dtype=float)) ** 2

        def sigma_theta(r):
            return P0 + (P0 - pR) * (R / np.asarray(r, dtype=float)) ** 2

        def u(r):
            return (P0 - pR) * R**2 / (2.0 * G * np.asarray(r, dtype=float))
        return sigma_r, sigma_theta, u

    if p >= p_cr:
        sr, st, u = elastic(a, p)
        return {"R0": a, "u_wall": float(u(a)), "p_cr": p_cr, "sigma_r": sr, "sigma_theta": st, "u": u}
    if mb * p / ucs + s <= 0.0:
        raise ValueError("the support pressure is below the criterion's tensile apex: the wall cannot stand")

    def hoop(sr):
        return sr + ucs * np.maximum(mb * sr / ucs + s, 0.0) ** a_hb

    def rhs(r, y):
        sr, _ = y
        st = hoop(sr)
        d_r, d_t = sr - P0, st - P0  # compression-positive changes from P0
        e_r = -(1.0 + nu) / E * ((1.0 - nu) * d_r - nu * d_t)
        e_t = -(1.0 + nu) / E * ((1.0 - nu) * d_t - nu * d_r)
        return [(st - sr) / r, (e_r + Kq * e_t) * r**Kq]

    def reach(r, y):
        return y[0] - p_cr
    reach.terminal, reach.direction = True, 1.0

    # integral I(r) = ∫_a^r (ε_r^e + Kψ ε_θ^e) ρ^Kψ dρ, so w(a) a^Kψ = w(R0) R0^Kψ - I(R0)
    span = (a, 10.0 * plastic_radius(P0, ucs, mb, s, a_hb, a, p))
    stress_scale = max(P0, ucs)
    sol = solve_ivp(rhs, span, [p, 0.0], method="DOP853", rtol=RTOL, events=reach, dense_output=True,
                    atol=[RTOL * stress_scale, RTOL * stress_scale / G * a ** (Kq + 1.0)])
    if sol.status != 1:
        raise ArithmeticError(f"the plastic zone's integration did not reach p_cr: {sol.message}")
    R0 = float(sol.t_events[0][0])
    w_R0 = -(P0 - p_cr) * R0 / (2.0 * G)
    WR0 = w_R0 * R0**Kq
    I_R0 = float(sol.y_events[0][0][1])
    out_sr, out_st, out_u = elastic(R0, p_cr)

    def sigma_r(r):
        r = np.asarray(r, dtype=float)
        inside = sol.sol(np.clip(r, a, R0))[0]
        return np.where(r <= R0, inside, out_sr(r))

    def sigma_theta(r):
        r = np.asarray(r, dtype=float)
        return np.where(r <= R0, hoop(sigma_r(r)), out_st(r))

    def u(r):
        r = np.asarray(r, dtype=float)
        inside = -(WR0 - I_R0 + sol.sol(np.clip(r, a, R0))[1]) / r**Kq
        return np.where(r <= R0, inside, out_u(r))

    return {"R0": R0, "u_wall": float(u(a)), "p_cr": p_cr, "sigma_r": sigma_r, "sigma_theta": sigma_theta, "u": u}


def ground_reaction_curve(P0: float, ucs: float, gsi: float, mi: float, disturbance: float, psi: float, E: float,
                          nu: float, a: float, n: int = 41, *, hb: tuple[float, float, float] | None = None) -> dict:
    """The ground reaction curve: support pressures ``p`` (n,) from P0 down to 0 (Pa) with the wall's
    inward convergence ``u_wall`` (m) and the plastic radius ``R0`` (m) of each (:func:`hoek_brown_hole`)."""
    p = np.linspace(P0, 0.0, n)
    rows = [hoek_brown_hole(P0, ucs, gsi, mi, disturbance, psi, E, nu, a, float(pi), hb=hb) for pi in p]
    return {"p": p, "u_wall": np.array([r["u_wall"] for r in rows]), "R0": np.array([r["R0"] for r in rows]),
            "p_cr": rows[0]["p_cr"]}
