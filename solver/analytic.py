"""Closed-form reference solutions for a lining ring in an infinite elastic medium.

Both assume plane strain, a weightless medium loaded at infinity by a vertical
pressure ``P`` and a horizontal pressure ``K P``, a frictionless (full-slip)
interface, and loads applied after the lining is in place ("external loading").
"""
from __future__ import annotations


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
                        thickness: float = 0.3, h: float = 0.1, inner: str = "active-set"):
    """The FE case that approximates these solutions: a weightless ground (E = 5e7,
    nu = 0.3) loaded by ``surface_load = P`` and side pressure ``K P`` (roller bottom),
    lining a = 2.5 m, nu_l = 0.2, with the domain ``radii`` outer radii each way.
    The lining keeps a token density (1 kg/m^3): the floating lining needs weight."""
    from .spec import CaseSpec

    b = 2.5 + thickness
    return CaseSpec(
        geometry=dict(inner_radius=2.5, thickness=thickness, width=radii * b + 1,
                      depth=radii * b + 1, height=2 * radii * b + 2),
        ground=dict(young=5.0e7, poisson=0.3, density=0.0),
        lining=dict(young=young_l, poisson=0.2, density=1.0),
        loads=dict(surface_load=P, lateral_ratio=K),
        boundaries=dict(side="pressure", bottom="roller"),
        mesh=dict(interface_size=h, far_size=16.0),
        solver=dict(inner=inner),
    )
