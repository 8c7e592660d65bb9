"""Closed-form reference solutions for a lining ring in an infinite elastic medium.

All assume plane strain and a weightless medium loaded at infinity by a vertical
pressure ``P`` and a horizontal pressure ``K P`` (compression positive).
``ring_pressure`` and ``thin_ring_cos2`` are for a frictionless (full-slip)
interface and loads applied after the lining is in place ("external loading");
``exact_ring`` is the exact thick-ring (annulus) solution for external or
excavation loading with a full-slip or bonded interface; ``kirsch_wall_displacement``
is the unlined hole and ``einstein_schwartz_slip_excavation`` the thin-ring
full-slip excavation solution.

``exact_ring``, ``kirsch_wall_displacement`` and ``einstein_schwartz_slip_excavation``
use the product's angle: θ in degrees from the crown (0 crown, 90 springline,
180 invert), so their cos 2θ amplitudes are minus those from the springline that
``thin_ring_cos2`` (and reference/closed-forms.md) use.
"""
from __future__ import annotations

from dataclasses import dataclass
from dataclasses import field as dc_field
from typing import Literal

import numpy as np


def ring_pressure(P: float, E: float, nu: float, E_l: float, nu_l: float, a: float, b: float) -> float:
    """Uniform contact pressure q (Pa) for hydrostatic loading (K = 1), thick ring a < r < b.

    q = 2 (1 - nu) P / (1 + E lambda_l / (1 + nu)), with the ring's radial compliance
    lambda_l = (1 + nu_l)((1 - 2 nu_l) b^2 + a^2) / (E_l (b^2 - a^2)) (1/Pa). The mean
    thrust is q b.
    """
    lam_l = (1 + nu_l) * ((1 - 2 * nu_l) * b**2 + a**2) / (E_l * (b**2 - a**2))
    return 2 * (1 - nu) * P / (1 + E * lam_l / (1 + nu))


def thin_ring_cos2(P: float, K: float, E: float, nu: float, E_l: float, nu_l: float,
                   R: float, t: float) -> tuple[float, float]:
    """cos 2θ amplitudes (θ from the springline) of moment M2 (N·m/m) and pressure p2 (Pa).

    M2 = 6 P R^2 (1 - K)(1 - nu) / D2, D2 = (C + F)(1 - nu) + 15 - 18 nu,
    C = E R (1 - nu_l^2) / (E_l t (1 - nu^2)), F = E R^3 (1 - nu_l^2) / (E_l I (1 - nu^2)),
    I = t^3 / 12, p2 = -3 M2 / R^2; R is the centreline radius. Error ~ t / 2R.
    """
    inertia = t**3 / 12
    C = E * R * (1 - nu_l**2) / (E_l * t * (1 - nu**2))
    F = E * R**3 * (1 - nu_l**2) / (E_l * inertia * (1 - nu**2))
    D2 = (C + F) * (1 - nu) + 15 - 18 * nu
    M2 = 6 * P * R**2 * (1 - K) * (1 - nu) / D2
    return M2, -3 * M2 / R**2


def ring_in_medium_case(*, radii: float, K: float, P: float = 1.0e5, young_l: float = 3e10,
                        thickness: float = 0.3, h: float = 0.1, inner: str = "active-set",
                        loading: str = "external", interface: str = "frictionless",
                        deconfinement: float = 0.0, lining_density: float = 1.0, friction: float = 0.0):
    """The FE case that approximates these solutions: a weightless ground (E = 5e7,
    nu = 0.3) loaded by ``surface_load = P`` and side pressure ``K P`` (roller bottom),
    lining a = 2.5 m, nu_l = 0.2, with the domain ``radii`` outer radii each way.
    ``loading="external"`` is ``wished-in-place``; ``"excavation"`` is ``deconfinement``
    with the uniform in-situ stress (-K P, -P) and λd = ``deconfinement``.
    The lining keeps a token density (1 kg/m^3): the floating lining needs weight."""
    from .spec import CaseSpec

    b = 2.5 + thickness
    return CaseSpec(
        geometry=dict(inner_radius=2.5, thickness=thickness, width=radii * b + 1,
                      depth=radii * b + 1, height=2 * radii * b + 2),
        ground=dict(young=5.0e7, poisson=0.3, density=0.0),
        lining=dict(young=young_l, poisson=0.2, density=lining_density),
        loads=dict(surface_load=P, lateral_ratio=K),
        boundaries=dict(side="pressure", bottom="roller"),
        mesh=dict(interface_size=h, far_size=16.0),
        solver=dict(inner=inner),
        excavation=dict(method="wished-in-place" if loading == "external" else "deconfinement",
                        deconfinement=deconfinement),
        interface=dict(model=interface, friction=friction),
        design=dict(reinforcement_area=0.0),  # plain section: valid for any thickness
    )


# ---------------------------------------------------------------------------
# Exact thick ring in an infinite medium (Michell / Airy stress functions)
# ---------------------------------------------------------------------------
#
# Internally the polar angle φ is measured from the springline (+x), counter-
# clockwise, and the fields are written with ρ = r/b and an Airy function
# Φ = b² Σ c_k ψ_k(ρ) (coefficients c_k in Pa). The terms are
#   n = 0: ψ = ln ρ, ρ²;   n = 2: ψ = (ρ², ρ⁴, ρ⁻², 1) · cos 2φ.
# σrr = Φ_r/r + Φ_φφ/r², σφφ = Φ_rr, σrφ = −∂r(Φ_φ/r); the plane-strain
# displacements of each term were integrated with sympy (no rigid modes for
# n = 2; the n = 0 rotation is dropped); tests/solver/test_analytic.py
# re-derives the table. Cos 2φ terms go with u_r, σrr, σφφ; sin 2φ with σrφ, u_φ.


def _n0(rho, nu: float) -> dict[str, np.ndarray]:
    """n = 0 terms [ln ρ, ρ²]: stresses (Pa per unit c), G u_r / b, ψ and dψ/dρ."""
    rho = np.asarray(rho, dtype=float)
    one = np.ones_like(rho)
    col = lambda *v: np.stack(np.broadcast_arrays(*v), axis=-1)  # noqa: E731
    return dict(srr=col(rho**-2, 2 * one), stt=col(-rho**-2, 2 * one),
                gur=col(-0.5 / rho, (1 - 2 * nu) * rho),
                psi=col(np.log(rho), rho**2), dpsi=col(1 / rho, 2 * rho))


def _n2(rho, nu: float) -> dict[str, np.ndarray]:
    """n = 2 terms [ρ², ρ⁴, ρ⁻², 1]·cos 2φ: amplitudes of σrr, σφφ, G u_r / b (cos 2φ),
    σrφ, G u_φ / b (sin 2φ), and ψ, dψ/dρ."""
    rho = np.asarray(rho, dtype=float)
    zero, one = np.zeros_like(rho), np.ones_like(rho)
    col = lambda *v: np.stack(np.broadcast_arrays(*v), axis=-1)  # noqa: E731
    return dict(
        srr=col(-2 * one, zero, -6 * rho**-4, -4 * rho**-2),
        stt=col(2 * one, 12 * rho**2, 6 * rho**-4, zero),
        srt=col(2 * one, 6 * rho**2, -6 * rho**-4, -2 * rho**-2),
        gur=col(-rho, -2 * nu * rho**3, rho**-3, 2 * (1 - nu) / rho),
        gut=col(rho, (3 - 2 * nu) * rho**3, rho**-3, -(1 - 2 * nu) / rho),
        psi=col(rho**2, rho**4, rho**-2, one), dpsi=col(2 * rho, 4 * rho**3, -2 * rho**-3, zero))


def _solve_rows(rows: list, rhs: list) -> np.ndarray:
    A, y = np.array(rows, dtype=float), np.array(rhs, dtype=float)
    s = np.abs(A).max(axis=1)  # row equilibration: stress and displacement rows differ by ~G
    return np.linalg.solve(A / s[:, None], y / s)


@dataclass(frozen=True)
class RingSolution:
    """Exact plane-strain solution of an elastic ring a < r < b in an infinite medium.

    Angles θ are in degrees from the crown (0 crown, 90 springline, 180 invert).
    Every quantity is ``X0 + X2 cos 2θ`` or ``X2 sin 2θ``:

    Attributes
    ----------
    p0, p2 : float
        Contact pressure λ(θ) = p0 + p2 cos 2θ (Pa, compression positive): the normal
        traction between ground and ring at r = b (λ = −σrr(b)).
    s2 : float
        Interface shear traction on the ring s(θ) = s2 sin 2θ (Pa, positive towards
        increasing θ, i.e. s = σrθ(b) of the ring with e_θ along increasing θ); 0 for slip.
    N0, N2 : float
        Thrust N(θ) = N0 + N2 cos 2θ (N/m, compression positive), N = −∫_a^b σθθ dr.
    M0, M2 : float
        Moment M(θ) = M0 + M2 cos 2θ (N·m/m, positive when the inner fibre is in
        compression), M = +∫_a^b σθθ (r − r_mid) dr with σθθ tension positive and
        r_mid = (a + b)/2. M0 is the small thick-ring (Lamé) part of the n = 0 field.
    V2 : float
        Shear force V(θ) = V2 sin 2θ (N/m), V = ∫_a^b σrθ dr: the radial (outward
        positive) force of the invert side on the crown side of a cut at θ.
    ur_ground0, ur_ground2 : float
        Ground radial displacement at r = b (m, outward positive); for excavation
        loading measured from the pre-stressed state, for external loading from the
        stress-free state (including the uniform far-field strain, zero at the axis).
    ut_ground2 : float
        Ground tangential displacement at r = b, u_θ = ut_ground2 sin 2θ (m, towards
        increasing θ).
    ur_lining_b0, ur_lining_b2, ur_lining_a0, ur_lining_a2 : float
        Lining radial displacement at r = b and at r = a (m, outward positive).
    ut_lining2 : float
        Lining tangential displacement at r = b (m, sin 2θ, towards increasing θ).
    loading, interface : str
        The case solved; ``params`` holds (P, K, E, nu, E_l, nu_l, a, b).
    """

    p0: float
    p2: float
    s2: float
    N0: float
    N2: float
    M0: float
    M2: float
    V2: float
    ur_ground0: float
    ur_ground2: float
    ut_ground2: float
    ur_lining_b0: float
    ur_lining_b2: float
    ur_lining_a0: float
    ur_lining_a2: float
    ut_lining2: float
    loading: str
    interface: str
    params: tuple = dc_field(repr=False)
    # Michell coefficients (Pa), φ from the springline: ring [lnρ, ρ²], [ρ², ρ⁴, ρ⁻², 1];
    # ground stress and ground displacement coefficients (the latter drop the uniform
    # field for excavation loading).
    _coef: tuple = dc_field(repr=False, compare=False)

    def at(self, theta_deg) -> dict[str, np.ndarray]:
        """Evaluate the interface and lining quantities at θ (deg from the crown).

        Returns a dict of arrays shaped like ``theta_deg``: ``contact_pressure`` (Pa),
        ``shear_traction`` (Pa), ``thrust`` (N/m), ``moment`` (N·m/m), ``shear`` (N/m),
        ``ground_ur``, ``ground_ut``, ``lining_ur_outer``, ``lining_ur_inner``,
        ``lining_ut_outer`` (m), with the signs of the attributes.
        """
        th = np.radians(np.asarray(theta_deg, dtype=float))
        c, s = np.cos(2 * th), np.sin(2 * th)
        return dict(
            contact_pressure=self.p0 + self.p2 * c, shear_traction=self.s2 * s,
            thrust=self.N0 + self.N2 * c, moment=self.M0 + self.M2 * c, shear=self.V2 * s,
            ground_ur=self.ur_ground0 + self.ur_ground2 * c, ground_ut=self.ut_ground2 * s,
            lining_ur_outer=self.ur_lining_b0 + self.ur_lining_b2 * c,
            lining_ur_inner=self.ur_lining_a0 + self.ur_lining_a2 * c,
            lining_ut_outer=self.ut_lining2 * s)

    def field(self, r, theta_deg, body: Literal["ring", "ground"]) -> dict[str, np.ndarray]:
        """Stress and displacement of one body at radius r (m) and θ (deg from the crown).

        Valid for a ≤ r ≤ b (``"ring"``) or r ≥ b (``"ground"``); r and θ broadcast.
        Returns ``sigma_rr``, ``sigma_tt``, ``sigma_rt`` (Pa, tension positive; total
        stress in the ground; σrθ with e_θ towards increasing θ), ``u_r`` (m, outward)
        and ``u_t`` (m, towards increasing θ), displacements as in the attributes.
        """
        P, K, E, nu, E_l, nu_l, a, b = self.params
        ring0, ring2, g0, g2, g0u, g2u = self._coef
        if body == "ring":
            n, G, s0, s2, u0, u2 = nu_l, E_l / (2 * (1 + nu_l)), ring0, ring2, ring0, ring2
        elif body == "ground":
            n, G, s0, s2, u0, u2 = nu, E / (2 * (1 + nu)), g0, g2, g0u, g2u
        else:
            raise ValueError(f"body must be 'ring' or 'ground', not {body!r}")
        r, th = np.broadcast_arrays(np.asarray(r, float), np.radians(np.asarray(theta_deg, float)))
        b0, b2 = _n0(r / b, n), _n2(r / b, n)
        c, s = np.cos(2 * th), np.sin(2 * th)
        # φ from the springline → θ from the crown: cos 2φ = −cos 2θ, sin 2φ = sin 2θ, e_φ = −e_θ
        return dict(
            sigma_rr=b0["srr"] @ s0 - (b2["srr"] @ s2) * c,
            sigma_tt=b0["stt"] @ s0 - (b2["stt"] @ s2) * c,
            sigma_rt=-(b2["srt"] @ s2) * s,
            u_r=(b / G) * (b0["gur"] @ u0 - (b2["gur"] @ u2) * c),
            u_t=-(b / G) * (b2["gut"] @ u2) * s)


def _ring_mode0(alpha, nu, nu_l, G, G_l, B0, keep):
    """The axisymmetric (n = 0) Michell coefficients of ring and ground, unknowns [L, Q, gL]:
    the ring's (2,), the ground's and the ground's displacement's (2,) each."""
    ra, rb, gb = _n0(alpha, nu_l), _n0(1.0, nu_l), _n0(1.0, nu)
    x0 = _solve_rows(
        [[*ra["srr"], 0.0],                                      # σrr(a) = 0
         [*rb["srr"], -gb["srr"][0]],                            # σrr continuous at b
         [*(rb["gur"] / G_l), -gb["gur"][0] / G]],               # u_r continuous at b
        [0.0, gb["srr"][1] * B0, keep * gb["gur"][1] * B0 / G])
    return x0[:2], np.array([x0[2], B0]), np.array([x0[2], keep * B0])


def _ring_mode2(alpha, nu, nu_l, G, G_l, A_inf, keep, interface):
    """The cos 2φ (n = 2) Michell coefficients, unknowns [A, B, C, D, gC, gD]: the ring's (4,),
    the ground's and the ground's displacement's (4,) each."""
    ra, rb, gb = _n2(alpha, nu_l), _n2(1.0, nu_l), _n2(1.0, nu)
    z2 = [0.0, 0.0]
    rows = [[*ra["srr"], *z2],                                   # σrr(a) = 0
            [*ra["srt"], *z2],                                   # σrφ(a) = 0
            [*rb["srr"], *(-gb["srr"][2:])],                     # σrr continuous
            [*(rb["gur"] / G_l), *(-gb["gur"][2:] / G)]]         # u_r continuous
    rhs = [0.0, 0.0, gb["srr"][0] * A_inf, keep * gb["gur"][0] * A_inf / G]
    if interface == "slip":
        rows += [[*rb["srt"], *z2], [0.0] * 4 + [*gb["srt"][2:]]]  # no shear on either side
        rhs += [0.0, -gb["srt"][0] * A_inf]
    else:
        rows += [[*rb["srt"], *(-gb["srt"][2:])],                  # σrφ continuous
                 [*(rb["gut"] / G_l), *(-gb["gut"][2:] / G)]]      # u_φ continuous
        rhs += [gb["srt"][0] * A_inf, keep * gb["gut"][0] * A_inf / G]
    x2 = _solve_rows(rows, rhs)
    return x2[:4], np.array([A_inf, 0.0, *x2[4:]]), np.array([keep * A_inf, 0.0, *x2[4:]])


def _ring_section_forces(ring0, ring2, alpha, nu_l, a, b):
    """N0, N2, M0, M2, V2 of the ring in φ (from the horizontal), by section integrals of
    Φ = b² ψ(ρ): ∫σφφ dr = [Φ_r] = b[ψ'], ∫σφφ r dr = [rΦ_r − Φ] = b²[ρψ' − ψ],
    ∫σrφ dr = −[Φ_φ / r] = 2b[ψ/ρ] (n = 2), each from ρ = a/b to 1."""
    r_mid = 0.5 * (a + b)

    def jump(basis, f):
        return f(basis(1.0, nu_l), 1.0) - f(basis(alpha, nu_l), alpha)

    d_dpsi0, d_dpsi2 = (jump(bas, lambda t, x: t["dpsi"]) for bas in (_n0, _n2))
    d_rdpsi0, d_rdpsi2 = (jump(bas, lambda t, x: x * t["dpsi"] - t["psi"]) for bas in (_n0, _n2))
    N0 = -b * d_dpsi0 @ ring0
    N2_phi = -b * d_dpsi2 @ ring2
    M0 = b**2 * d_rdpsi0 @ ring0 + r_mid * N0
    M2_phi = b**2 * d_rdpsi2 @ ring2 + r_mid * N2_phi
    V2_phi = 2 * b * jump(_n2, lambda t, x: t["psi"] / x) @ ring2  # ∫σrφ dr (sin 2φ)
    return N0, N2_phi, M0, M2_phi, V2_phi


def exact_ring(P: float, K: float, E: float, nu: float, E_l: float, nu_l: float,
               a: float, b: float, *, loading: Literal["external", "excavation"],
               interface: Literal["slip", "bonded"]) -> RingSolution:
    """Exact plane-strain solution: elastic ring a < r < b in an infinite elastic medium.

    Far field σyy = −P, σxx = −K P (tension positive; P > 0 is compression). The
    ring's inner surface is free; the ground's hole has radius b (no gap).

    Parameters
    ----------
    P : float
        Vertical far-field pressure (Pa, compression positive).
    K : float
        Lateral ratio (1): horizontal far-field pressure K P.
    E, nu : float
        Ground Young's modulus (Pa) and Poisson ratio.
    E_l, nu_l : float
        Lining Young's modulus (Pa) and Poisson ratio.
    a, b : float
        Inner and outer lining radii (m), 0 < a < b.
    loading : {"external", "excavation"}
        ``"external"``: both bodies start stress-free, the far field is applied to the
        ground–ring system (ground displacement from the stress-free state).
        ``"excavation"``: the ground is pre-stressed by the uniform far field, the hole
        is cut and the ring placed stress-free at once (deconfinement 0): the ground
        field is the uniform initial field plus a field vanishing at infinity loaded at
        r = b by the released traction minus the contact traction; the ground
        displacement is that of the latter (measured from the pre-stressed state).
    interface : {"slip", "bonded"}
        ``"slip"``: continuity of u_r and σrr, zero shear on both sides at r = b.
        ``"bonded"``: continuity of u_r, u_θ, σrr, σrθ at r = b.

    Returns
    -------
    RingSolution
        cos 2θ / sin 2θ amplitudes with θ from the crown; see its docstring for signs.

    Notes
    -----
    Michell fields with n = 0 (ln r, r²) and n = 2 (r², r⁴, r⁻², 1)·cos 2φ terms in the
    ring, decaying terms (ln r; r⁻², 1) plus the uniform far field in the ground; the
    3 + 6 linear conditions are solved with numpy (≈0.1 ms). The n = 0 terms do not
    depend on the interface. For slip, the quarter ring's moment balance gives
    M2 = r_mid N2 exactly (any thickness).
    """
    if loading not in ("external", "excavation"):
        raise ValueError(f"loading must be 'external' or 'excavation', not {loading!r}")
    if interface not in ("slip", "bonded"):
        raise ValueError(f"interface must be 'slip' or 'bonded', not {interface!r}")
    if not (0 < a < b) or E <= 0 or E_l <= 0:
        raise ValueError("need 0 < a < b and positive moduli")
    G, G_l = E / (2 * (1 + nu)), E_l / (2 * (1 + nu_l))
    alpha = a / b
    B0, A_inf = -P * (1 + K) / 4, -P * (1 - K) / 4  # uniform field: Φ = B0 r² + A_inf r² cos 2φ
    keep = 1.0 if loading == "external" else 0.0    # does the ground displacement include it?

    ring0, g0, g0u = _ring_mode0(alpha, nu, nu_l, G, G_l, B0, keep)
    ring2, g2, g2u = _ring_mode2(alpha, nu, nu_l, G, G_l, A_inf, keep, interface)
    N0, N2_phi, M0, M2_phi, V2_phi = _ring_section_forces(ring0, ring2, alpha, nu_l, a, b)
    gb = _n2(1.0, nu)

    ga0, ga2 = _n0(alpha, nu_l), _n2(alpha, nu_l)
    rb0, rb2, gb0 = _n0(1.0, nu_l), _n2(1.0, nu_l), _n0(1.0, nu)
    # φ → θ from the crown: every n = 2 amplitude changes sign (see RingSolution.field)
    return RingSolution(
        p0=float(-rb0["srr"] @ ring0), p2=float(rb2["srr"] @ ring2),
        s2=float(-rb2["srt"] @ ring2),
        N0=float(N0), N2=float(-N2_phi), M0=float(M0), M2=float(-M2_phi), V2=float(-V2_phi),
        ur_ground0=float(b / G * gb0["gur"] @ g0u), ur_ground2=float(-b / G * gb["gur"] @ g2u),
        ut_ground2=float(-b / G * gb["gut"] @ g2u),
        ur_lining_b0=float(b / G_l * rb0["gur"] @ ring0),
        ur_lining_b2=float(-b / G_l * rb2["gur"] @ ring2),
        ur_lining_a0=float(b / G_l * ga0["gur"] @ ring0),
        ur_lining_a2=float(-b / G_l * ga2["gur"] @ ring2),
        ut_lining2=float(-b / G_l * rb2["gut"] @ ring2),
        loading=loading, interface=interface, params=(P, K, E, nu, E_l, nu_l, a, b),
        _coef=(ring0, ring2, g0, g2, g0u, g2u))


def kirsch_wall_displacement(P: float, K: float, E: float, nu: float, a: float, theta_deg):
    """Radial wall displacement (m, outward positive) of an unlined circular hole (Kirsch).

    Plane strain, hole radius ``a`` (m) cut in a medium pre-stressed by σyy = −P,
    σxx = −K P (P > 0 compression, Pa), displacement measured from the pre-stressed
    state, θ in degrees from the crown:
    u_r = −(P a / 4G)[(1 + K) + (1 − K)(3 − 4ν) cos 2θ], G = E / (2(1 + ν)).
    """
    G = E / (2 * (1 + nu))
    c = np.cos(2 * np.radians(np.asarray(theta_deg, dtype=float)))
    return -(P * a / (4 * G)) * ((1 + K) + (1 - K) * (3 - 4 * nu) * c)


def einstein_schwartz_slip_excavation(P: float, K: float, E: float, nu: float, E_l: float,
                                      nu_l: float, R: float, t: float) -> tuple[float, float, float]:
    """Thin-ring full-slip excavation solution (Einstein & Schwartz 1979), θ from the crown.

    Returns (M2, N0, N2): M(θ) = M2 cos 2θ (N·m/m, + inner fibre compressed) and
    N(θ) = N0 + N2 cos 2θ (N/m, compression +) with
    N0 = ½(1+K)(1 − a0*) P R, N2 = M2 / R = −½(1−K)(1 − 2a2*) P R,
    a0* = C F (1−ν) / [C + F + C F (1−ν)], a2* = (F + 6)(1−ν) / [2F(1−ν) + 6(5 − 6ν)],
    C = E R (1 − νl²) / [El t (1 − ν²)], F = E R³ (1 − νl²) / [El I (1 − ν²)], I = t³/12.
    R is the centreline radius (m), t the thickness (m); error ~ t / 2R.
    """
    C = E * R * (1 - nu_l**2) / (E_l * t * (1 - nu**2))
    F = E * R**3 * (1 - nu_l**2) / (E_l * (t**3 / 12) * (1 - nu**2))
    a0 = C * F * (1 - nu) / (C + F + C * F * (1 - nu))
    a2 = (F + 6) * (1 - nu) / (2 * F * (1 - nu) + 6 * (5 - 6 * nu))
    N0 = 0.5 * (1 + K) * (1 - a0) * P * R
    M2 = -0.5 * (1 - K) * (1 - 2 * a2) * P * R**2
    return M2, N0, M2 / R


# ---------------------------------------------------------------------------
# Reading a result the way the closed forms are written
# ---------------------------------------------------------------------------


def cos2_amplitude(ds, values) -> float:
    """cos 2θ amplitude (θ from the crown) of interface ``values`` of a result Dataset.

    Projected with the interface quadrature weights (those of the nodal contact
    forces): the vertex and edge-node values of quadratic elements alternate slightly
    about the smooth field, which a trapezoid in θ would misread.
    """
    w, c = ds.weight.values, np.cos(2 * np.radians(ds.theta.values))
    return float(np.sum(w * np.asarray(values) * c) / np.sum(w * c * c))


def interface_mean(ds, values) -> float:
    """Mean of interface ``values`` over the half ring, weighted by the interface quadrature."""
    w = ds.weight.values
    return float(np.sum(w * np.asarray(values)) / np.sum(w))


def salencon(P0: float, c: float, phi: float, psi: float, E: float, nu: float, a: float, p: float = 0.0,
             n: int = 4001) -> dict:
    """Salençon's hole of radius ``a`` in an isotropic Mohr–Coulomb medium under ``P0``, supported
    by ``p`` (compression positive, Pa; angles in degrees; plane strain, σzz intermediate):
    the plastic radius ``R0``, the wall's inward displacement ``u_wall`` (m) and the stresses
    ``sigma_r(r)``, ``sigma_theta(r)`` as functions (``../shared/reference/closed-forms.md``)."""
    sp, sq = np.sin(np.radians(phi)), np.sin(np.radians(psi))
    Kp, Kq = (1 + sp) / (1 - sp), (1 + sq) / (1 - sq)
    sc = 2 * c * np.cos(np.radians(phi)) / (1 - sp)
    G = E / (2 * (1 + nu))
    p_cr = (2 * P0 - sc) / (1 + Kp)
    if p >= p_cr:
        return {"R0": a, "u_wall": (P0 - p) * a / (2 * G), "p_cr": p_cr,
                "sigma_r": lambda r: P0 - (P0 - p) * (a / r) ** 2, "sigma_theta": lambda r: P0 + (P0 - p) * (a / r) ** 2}
    R0 = a * (2 * (P0 * (Kp - 1) + sc) / ((1 + Kp) * ((Kp - 1) * p + sc))) ** (1 / (Kp - 1))

    def sigma_r(r):
        r = np.asarray(r, dtype=float)
        plastic = (p + sc / (Kp - 1)) * (r / a) ** (Kp - 1) - sc / (Kp - 1)
        return np.where(r <= R0, plastic, P0 - (P0 - p_cr) * (R0 / r) ** 2)

    def sigma_theta(r):
        r = np.asarray(r, dtype=float)
        return np.where(r <= R0, Kp * sigma_r(r) + sc, P0 + (P0 - p_cr) * (R0 / r) ** 2)

    # compatibility: d(w r^Kq)/dr = (eps_r^e + Kq eps_theta^e) r^Kq from R0 (w outward, strains tension positive)
    r = np.linspace(R0, a, n)
    dr_, dt_ = sigma_r(r) - P0, sigma_theta(r) - P0  # compression-positive changes
    e_r = -(1 + nu) / E * ((1 - nu) * dr_ - nu * dt_)
    e_t = -(1 + nu) / E * ((1 - nu) * dt_ - nu * dr_)
    integrand = (e_r + Kq * e_t) * r**Kq
    w_R0 = -(P0 - p_cr) * R0 / (2 * G)
    w_a = (w_R0 * R0**Kq + np.trapezoid(integrand, r)) / a**Kq
    return {"R0": R0, "u_wall": -w_a, "p_cr": p_cr, "sigma_r": sigma_r, "sigma_theta": sigma_theta}
