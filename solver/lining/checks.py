"""EN 1992-1-1 checks of the lining section beside the N–M envelope (SPEC §9.3): shear and crack width.

Per metre of tunnel (b = 1 m, h = ``thickness``), forces as in :mod:`solver.lining.design`: thrust
``N`` (N/m) compression positive, moment ``M`` (N·m/m), shear ``V`` (N/m). ULS actions are
γF·V and γF·M with the thrust taken at whichever of γF·N and 1.0·N is worse (a lower thrust is
unfavourable where bending or shear governs); SLS (crack width) takes the characteristic forces
(γF = 1).

Shear, reinforced section (As > 0), §6.2.2 (6.2), members without shear reinforcement:
V_Rd,c = [max(C_Rd,c k (100 ρl fck)^⅓, v_min) + k1 σcp] b d, C_Rd,c = 0.18/γc, k = 1 + √(200/d) ≤ 2
(d = h − d1 in mm), ρl = As/(b d) ≤ 0.02 (the bars of the tension face), v_min = 0.035 k^1.5 fck^½,
k1 = 0.15, σcp = N_Ed/(b h) ≤ 0.2 fcd (MPa; a tension is negative, V_Rd,c ≥ 0). The flexurally
uncracked resistance (6.4) is not used (conservative).

Shear, plain section (As = 0), §12.6.3: τcp = k V_Ed / Acc ≤ fcvd (12.4), k = 1.5; Acc the
compressed area of the linear-elastic no-tension section, b·min(h, 3(h/2 − e)), e = |M_Ed|/N_Ed;
σcp = N_Ed/Acc; fcvd = √(fctd² + σcp fctd − ((σcp − σc,lim)/2)²) with the last term only where
σcp > σc,lim = fcd − 2√(fctd (fctd + fcd)) (12.5-12.7); fcd = αcc,pl fck/γc, fctd = αct,pl
fctk,0.05/γc, αcc,pl = αct,pl = 0.8, fctk,0.05 = 0.7 fctm. A section whose thrust is a tension or
lies outside the section (e ≥ h/2) has no compressed area: V_Rd = 0.

Crack width, §7.3.4, characteristic actions: the section is cracked where the largest tensile
stress of the gross section, −N/(b h) + 6|M|/(b h²), exceeds fctm; else w = 0. Cracked: the
linear-elastic no-tension section with both bar layers (αe = Es/Ecm, short term) gives the
neutral axis x and the tension bars' stress σs; then (7.8) w_k = s_r,max (εsm − εcm),
(7.9) εsm − εcm = max([σs − kt fctm (1 + αe ρp,eff)/ρp,eff]/Es, 0.6 σs/Es) with kt = 0.4 (long
term), ρp,eff = As/(b hc,ef), hc,ef = min(2.5 (h − d), (h − x)/3, h/2); (7.11) s_r,max =
k3 c + k1 k2 k4 φ/ρp,eff with k1 = 0.8, k3 = 3.4, k4 = 0.425, c = d1 − φ/2 (the cover to the bars
of diameter φ = ``design.bar_diameter``), k2 = 0.5 in bending and (ε1 + ε2)/(2 ε1) (7.13) when the
whole section is in tension; (7.14) s_r,max = 1.3 (h − x) where the bar spacing π φ²/(4 As) exceeds
5 (c + φ/2). A plain section that cracks has no crack-width control (§12 has none; its cracks are
not held by bars): its crack width is ``inf``.
"""
from __future__ import annotations

import math

import numpy as np

from .design import ES, GAMMA_C, fcd

__all__ = ["fctm", "ecm", "design_thrusts", "shear_resistance", "shear_utilization", "crack_width"]

C_RD_C = 0.18 / GAMMA_C    #: C_Rd,c of (6.2.a)
K1_SHEAR = 0.15            #: k1 of (6.2.a)
RHO_L_MAX = 0.02           #: upper limit of ρl in (6.2.a)
K_PLAIN = 1.5              #: k of (12.4)
ALPHA_CT_PL = 0.8          #: αct,pl of 12.3.1
KT = 0.4                   #: kt of (7.9), long-term loading
K1_BOND, K3, K4 = 0.8, 3.4, 0.425   #: (7.11), high-bond bars
_BISECTIONS = 12      # in t: a finite bracket of x, then Newton's method kept in it
_NEWTON = 40          # at most; it stops where x no longer moves


def fctm(fck: float) -> float:
    """Mean tensile strength (Pa), Table 3.1: 0.30 fck^⅔ up to C50/60, 2.12 ln(1 + fcm/10) above."""
    f = fck / 1e6
    return 1e6 * (0.30 * f ** (2.0 / 3.0) if f <= 50.0 else 2.12 * math.log(1.0 + (f + 8.0) / 10.0))


def ecm(fck: float) -> float:
    """Secant modulus of concrete (Pa), Table 3.1: 22 (fcm/10)^0.3 GPa, fcm = fck + 8 MPa."""
    return 22e9 * ((fck / 1e6 + 8.0) / 10.0) ** 0.3


def design_thrusts(N, design) -> tuple[np.ndarray, np.ndarray]:
    """The two ULS thrusts (N/m) checked with γF·M and γF·V: γF·N and 1.0·N."""
    N = np.asarray(N, float)
    return design.load_factor * N, N


def _shear_reinforced(n_ed, h, design, width):
    d = h - design.axis_distance
    k = min(1.0 + math.sqrt(0.2 / d), 2.0)        # √(200/d) with d in mm
    rho = min(design.reinforcement_area / (width * d), RHO_L_MAX)
    f = design.concrete_strength / 1e6
    v = max(C_RD_C * k * (100.0 * rho * f) ** (1.0 / 3.0), 0.035 * k ** 1.5 * math.sqrt(f))   # MPa
    sigma_cp = np.minimum(n_ed / (width * h), 0.2 * fcd(design.concrete_strength)) / 1e6      # MPa
    return np.maximum(v + K1_SHEAR * sigma_cp, 0.0) * 1e6 * width * d


def _shear_plain(n_ed, m_ed, h, design, width):
    f_cd = fcd(design.concrete_strength, plain=True)
    f_ctd = ALPHA_CT_PL * 0.7 * fctm(design.concrete_strength) / GAMMA_C
    n = np.asarray(n_ed, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        e = np.where(n > 0, np.abs(m_ed) / np.where(n > 0, n, 1.0), np.inf)
    depth = np.clip(np.where(e <= h / 6.0, h, 3.0 * (0.5 * h - e)), 0.0, h)
    area = width * depth
    sigma = np.where(area > 0, n / np.where(area > 0, area, 1.0), 0.0)
    limit = f_cd - 2.0 * math.sqrt(f_ctd * (f_ctd + f_cd))
    excess = np.maximum(sigma - limit, 0.0)
    fcvd = np.sqrt(np.maximum(f_ctd ** 2 + sigma * f_ctd - (0.5 * excess) ** 2, 0.0))
    return fcvd * area / K_PLAIN


def shear_resistance(n_ed, m_ed, thickness: float, design, *, width: float = 1.0) -> np.ndarray:
    """V_Rd,c (N/m) of the section at the design thrust ``n_ed`` and moment ``m_ed`` (module
    docstring: (6.2) when reinforced, (12.4)-(12.7) when plain; only the plain one uses ``m_ed``)."""
    n_ed, m_ed = np.broadcast_arrays(np.asarray(n_ed, float), np.asarray(m_ed, float))
    if design.reinforcement_area > 0:
        return _shear_reinforced(n_ed, thickness, design, width)
    return _shear_plain(n_ed, m_ed, thickness, design, width)


def shear_utilization(N, M, V, thickness: float, design, *, width: float = 1.0) -> np.ndarray:
    """|γF V| / V_Rd,c, the worse of the thrusts γF·N and 1.0·N (with γF·M); 0 where V = 0,
    ``inf`` where V ≠ 0 meets no resistance."""
    gamma = design.load_factor
    v_ed = gamma * np.abs(np.asarray(V, float))
    m_ed = gamma * np.asarray(M, float)
    resistance = np.minimum(*(shear_resistance(n, m_ed, thickness, design, width=width)
                              for n in design_thrusts(N, design)))
    with np.errstate(divide="ignore", invalid="ignore"):
        eta = np.where(resistance > 0, v_ed / np.where(resistance > 0, resistance, 1.0), np.inf)
    return np.where(v_ed == 0, 0.0, eta)


def _cracked_stiffness(x, h, d1, area, alpha, width):
    """N̂, M̂ per unit curvature and Ec of the no-tension section with neutral axis depth ``x`` (m from
    the compressed face; any real: x ≤ 0 is a section wholly in tension, x ≥ h wholly compressed),
    and their derivatives in x: dN̂/dx = b·xc + 2αAs, dM̂/dx = b·xc(h - xc)/2 (the bars' moment about
    mid-depth does not change with x)."""
    xc = np.clip(x, 0.0, h)
    d = h - d1
    n = width * (x * xc - 0.5 * xc ** 2) + alpha * area * ((x - d1) + (x - d))
    m = width * (0.5 * h * x * xc - 0.5 * (x + 0.5 * h) * xc ** 2 + xc ** 3 / 3.0) \
        + alpha * area * ((x - d1) * (0.5 * h - d1) + (x - d) * (0.5 * h - d))
    return n, m, width * xc + 2.0 * alpha * area, 0.5 * width * xc * (h - xc)


def cracked_section(N, M, thickness: float, design, *, width: float = 1.0):
    """Neutral axis depth x (m from the face |M| compresses) and tension bar stress σs (Pa) of the
    cracked reinforced section under characteristic N (compression +) and M (module docstring).

    The direction of (N̂(x), M̂(x)) turns monotonically from pure tension (x → −∞) to pure
    compression (x → +∞); x is where it is the direction of (N, |M|): g(x) = N̂ |M| - M̂ N = 0, g
    rising through it. A few bisections on x = h/2 + h tan t give a finite bracket, Newton's method
    on g (its steps kept inside the shrinking bracket, else halving it) the root to round-off."""
    h, d1, As = thickness, design.axis_distance, design.reinforcement_area
    alpha = ES / ecm(design.concrete_strength)
    N, M = np.broadcast_arrays(np.asarray(N, float), np.abs(np.asarray(M, float)))
    lo, hi = np.full(N.shape, -0.5 * np.pi), np.full(N.shape, 0.5 * np.pi)
    for _ in range(_BISECTIONS):
        t = 0.5 * (lo + hi)
        n_hat, m_hat = _cracked_stiffness(0.5 * h + h * np.tan(t), h, d1, As, alpha, width)[:2]
        right = n_hat * M - m_hat * N > 0   # (N, |M|) lies counter-clockwise of the trial direction
        lo, hi = np.where(right, lo, t), np.where(right, t, hi)
    low, high = 0.5 * h + h * np.tan(lo), 0.5 * h + h * np.tan(hi)
    x = 0.5 * (low + high)
    for _ in range(_NEWTON):
        n_hat, m_hat, dn, dm = _cracked_stiffness(x, h, d1, As, alpha, width)
        g, slope = n_hat * M - m_hat * N, dn * M - dm * N
        low, high = np.where(g > 0, low, x), np.where(g > 0, x, high)
        with np.errstate(divide="ignore", invalid="ignore"):
            step = x - g / slope
        inside = (step >= low) & (step <= high)
        new = np.where(g == 0, x, np.where(inside, step, 0.5 * (low + high)))
        done = np.all(np.abs(new - x) <= 1e-14 * np.maximum(np.abs(x), h))
        x = new
        if done:
            break
    n_hat, m_hat = _cracked_stiffness(x, h, d1, As, alpha, width)[:2]
    kappa_ec = np.hypot(N, M) / np.hypot(n_hat, m_hat)     # Ec κ (Pa/m)
    return x, alpha * kappa_ec * (h - d1 - x)


def crack_width(N, M, thickness: float, design, *, width: float = 1.0) -> np.ndarray:
    """Characteristic crack width w_k (m) per station under characteristic N, M (γF = 1): 0 where the
    gross section's tensile stress stays within fctm, ``inf`` where a plain section cracks."""
    h = thickness
    N, M = np.broadcast_arrays(np.asarray(N, float), np.asarray(M, float))
    f_ct = fctm(design.concrete_strength)
    cracked = -N / (width * h) + 6.0 * np.abs(M) / (width * h * h) > f_ct
    out = np.zeros(N.shape)
    if not cracked.any():
        return out
    As = design.reinforcement_area
    if As <= 0:
        out[cracked] = np.inf
        return out
    x, sigma_s = cracked_section(N[cracked], M[cracked], h, design, width=width)
    d1, phi = design.axis_distance, design.bar_diameter
    alpha = ES / ecm(design.concrete_strength)
    hc = np.minimum(np.minimum(2.5 * d1, (h - np.maximum(x, 0.0)) / 3.0), 0.5 * h)
    rho = As / (width * hc)
    strain = np.maximum((sigma_s - KT * f_ct * (1.0 + alpha * rho) / rho) / ES, 0.6 * sigma_s / ES)
    k2 = np.where(x >= 0, 0.5, (h - 2.0 * x) / (2.0 * (h - x)))   # (7.13): ε2/ε1 = −x/(h − x)
    cover = max(d1 - 0.5 * phi, 0.0)   # bars wider than 2 d1: no cover left
    spacing = np.pi * phi ** 2 / (4.0 * As) * width
    if spacing > 5.0 * (cover + 0.5 * phi):
        s_r = 1.3 * (h - np.maximum(x, 0.0))
    else:
        s_r = K3 * cover + K1_BOND * k2 * K4 * phi / rho
    out[cracked] = np.maximum(s_r * strain, 0.0)   # bars in the compressed zone (x > d): no crack at them
    return out
