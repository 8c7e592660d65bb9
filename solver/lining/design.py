"""EN 1992-1-1 design check of the lining section: N–M envelope and utilization (SPEC §1.3).

Per metre of tunnel the section is a rectangle, width ``b`` (1 m) and depth
``h = thickness``. Thrust ``N`` (N/m) is compression positive and acts at mid-depth;
moment ``M`` (N·m/m) is positive when the inner fibre is in compression. The section
is symmetric, so the envelope is symmetric in ``M``.

Choices (EN 1992-1-1 recommended values):

- fcd = αcc fck / γc, fyd = fyk / γs, γc = 1.5, γs = 1.15; αcc = 1.0 for reinforced,
  αcc,pl = 0.8 for plain concrete (§12.3.1).
- Reinforced (``reinforcement_area`` As > 0 per face, at axis distance d1 from each
  face): strain compatibility, plane sections. Concrete: parabola-rectangle (3.17),
  no tension, εc2 = 2 ‰, εcu2 = 3.5 ‰, n = 2 for fck ≤ 50 MPa, the Table 3.1
  formulas above (fck ≤ 90 MPa). Steel: Es = 200 GPa, bilinear with a horizontal top
  branch at fyd (3.2.7(2) b)); the strain is limited to εud = 0.9 εuk = 4.5 %
  (εuk = 5 %, class B, Annex C) to define the tension pivot A. Gross concrete area
  (the concrete displaced by the compression bars is not deducted).
  Pivots: A (tension steel at −εud), B (εcu2 at the compressed face), C (εc2 at
  (1 − εc2/εcu2) h from the compressed face, 3/7 h for fck ≤ 50 MPa); pure compression
  is the uniform strain εc2 (6.1(5)): N = fcd b h + 2 As min(fyd, Es εc2); pure
  tension N = −2 As fyd.
- Plain (As = 0): §12.6.1 (12.10), rectangular stress block, no tension:
  N_Rd(e) = η fcd,pl b h (1 − 2e/h), |e| = |M|/N ≤ h/2, η = 1 for fck ≤ 50 MPa
  (3.1.7(3)). The envelope is M = ±N (h/2 − N / (2 η fcd,pl b)), 0 ≤ N ≤ η fcd,pl b h,
  closed through the origin, which is a vertex of it.
- The envelope is a polygon whose vertices lie on the exact curve. With the default
  501 vertices per branch the utilization errs by < 0.1 % along any ray (measured
  against 10× denser envelopes: ~2e-5 reinforced, ~2e-4 plain).
- Utilization η = 1 / (the factor by which (N, M) can be scaled along the ray from
  the origin before it leaves the envelope); η = 0 for (0, 0). ``inf`` means the
  section fails whatever the load level: for plain concrete a tension (N < 0),
  N = 0 with M ≠ 0, or an eccentricity |M|/N ≥ h/2 (outside the section; the
  polygon's wedge next to the origin misclassifies only thrusts below 1e-6 η fcd,pl b h).
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

__all__ = [
    "fcd", "fyd", "concrete_parameters", "section_forces", "interaction_envelope",
    "utilization", "design_utilization", "governing_thrust", "joint_utilization", "section_errors",
]

GAMMA_C, GAMMA_S = 1.5, 1.15
ALPHA_CC, ALPHA_CC_PL = 1.0, 0.8
ES = 2.0e11                #: steel modulus Es (Pa)
EPS_UD = 0.9 * 0.05        #: steel strain limit εud = 0.9 εuk, class B
MAX_FCK = 90.0e6           #: top of EN 1992-1-1 Table 3.1 (Pa)
MAX_STEEL_RATIO = 0.04     #: As,max / Ac, 9.2.1.1(3) and 9.5.2(3)
_U_MIN = 1.0e-6            #: plain envelope: smallest N / N_Rd(0) sampled before the origin
_GAUSS = np.polynomial.legendre.leggauss(12)


def fcd(fck: float, *, plain: bool = False) -> float:
    """Design compressive strength fcd = αcc fck / γc (Pa); αcc,pl = 0.8 if ``plain``."""
    return (ALPHA_CC_PL if plain else ALPHA_CC) * fck / GAMMA_C


def fyd(fyk: float) -> float:
    """Design yield strength of reinforcement fyd = fyk / γs (Pa)."""
    return fyk / GAMMA_S


def concrete_parameters(fck: float) -> tuple[float, float, float, float]:
    """Table 3.1 and 3.1.7(3) parameters for ``fck`` (Pa).

    Returns
    -------
    eps_c2, eps_cu2 : float
        Strain at peak stress and ultimate strain of the parabola-rectangle law (1).
    n : float
        Exponent of the parabola (1).
    eta : float
        Effective strength factor of the rectangular block (1).
    """
    f = fck / 1e6
    if f <= 50.0:
        return 2.0e-3, 3.5e-3, 2.0, 1.0
    eps_c2 = (2.0 + 0.085 * (f - 50.0) ** 0.53) * 1e-3
    eps_cu2 = (2.6 + 35.0 * ((90.0 - f) / 100.0) ** 4) * 1e-3
    n = 1.4 + 23.4 * ((90.0 - f) / 100.0) ** 4
    return eps_c2, eps_cu2, n, 1.0 - (f - 50.0) / 200.0


def section_forces(eps_inner, eps_outer, thickness: float, *, concrete_strength: float,
                   steel_strength: float, reinforcement_area: float, axis_distance: float,
                   width: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Resultants of the reinforced section for linear strain planes (compression positive).

    Parameters
    ----------
    eps_inner, eps_outer : array_like
        Strains (1) of the inner and outer concrete faces, broadcast together.
    thickness : float
        Section depth h (m).
    concrete_strength, steel_strength : float
        fck and fyk (Pa); fcd uses αcc = 1.0.
    reinforcement_area : float
        As per face (m² per metre of width).
    axis_distance : float
        d1, from each face to its bar axis (m).
    width : float
        b (m).

    Returns
    -------
    N : ndarray
        Thrust (N per ``width``), compression positive.
    M : ndarray
        Moment about mid-depth (N·m per ``width``), positive with the inner fibre compressed.
    """
    h = thickness
    et, eb = np.broadcast_arrays(np.asarray(eps_inner, float), np.asarray(eps_outer, float))
    eps_c2, _, n, _ = concrete_parameters(concrete_strength)
    f_c = fcd(concrete_strength)
    # split the depth where the stress law changes (ε = 0, ε = εc2): smooth pieces
    slope = eb - et
    safe = np.where(slope == 0.0, 1.0, slope)
    cuts = [np.where(slope == 0.0, 0.0, np.clip(h * (c - et) / safe, 0.0, h)) for c in (0.0, eps_c2)]
    y = np.sort(np.stack([np.zeros_like(et), *cuts, np.full_like(et, h)], axis=-1), axis=-1)
    x, w = _GAUSS
    a, c = y[..., :-1, None], y[..., 1:, None]
    yq = 0.5 * (a + c) + 0.5 * (c - a) * x
    wq = 0.5 * (c - a) * w
    eps = et[..., None, None] + slope[..., None, None] * yq / h
    ratio = np.clip(eps / eps_c2, 0.0, 1.0)
    sigma = f_c * (1.0 - (1.0 - ratio) ** n)
    N = width * np.sum(sigma * wq, axis=(-2, -1))
    M = width * np.sum(sigma * (0.5 * h - yq) * wq, axis=(-2, -1))
    d1 = axis_distance
    f_y = fyd(steel_strength)
    s_in = np.clip(ES * (et + slope * d1 / h), -f_y, f_y) * reinforcement_area
    s_out = np.clip(ES * (et + slope * (h - d1) / h), -f_y, f_y) * reinforcement_area
    return N + s_in + s_out, M + (s_in - s_out) * (0.5 * h - d1)


def _pivot_strains(p, h: float, d: float, eps_c2: float, eps_cu2: float):
    """Strains (inner, outer) on the pivot path p ∈ [0, 3]: A, then B, then C.

    p = 0 is pure tension (uniform −εud), p = 3 pure compression (uniform εc2).
    """
    p = np.asarray(p, float)
    # A: steel at depth d fixed at −εud, inner strain −εud → εcu2
    ta = -EPS_UD + np.clip(p, 0, 1) * (EPS_UD + eps_cu2)
    ba = ta + (-EPS_UD - ta) * h / d
    # B: inner strain εcu2, neutral axis x from the A/B limit to h
    x_ab = eps_cu2 * d / (eps_cu2 + EPS_UD)
    x = x_ab + np.clip(p - 1, 0, 1) * (h - x_ab)
    bb = eps_cu2 * (1.0 - h / x)
    # C: εc2 at (1 − εc2/εcu2) h, outer strain 0 → εc2
    bc = np.clip(p - 2, 0, 1) * eps_c2
    tc = eps_c2 + (eps_c2 - bc) * (eps_cu2 / eps_c2 - 1.0)
    inner = np.where(p <= 1, ta, np.where(p <= 2, eps_cu2, tc))
    outer = np.where(p <= 1, ba, np.where(p <= 2, bb, bc))
    return inner, outer


def _yield_corners(strains, p, h: float, d1: float, eps_yd: float) -> list[float]:
    """Parameters p where a bar layer reaches ±εyd: bracketed on the grid ``p``, bisected."""
    corners = []
    for y in (d1, h - d1):
        def excess(q, y=y):
            inner, outer = strains(q)
            return np.abs(inner + (outer - inner) * y / h) - eps_yd
        g = excess(p)
        i = np.flatnonzero(np.sign(g[:-1]) * np.sign(g[1:]) < 0)
        lo, hi = p[i], p[i + 1]
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            left = np.sign(excess(mid)) == np.sign(g[i])
            lo, hi = np.where(left, mid, lo), np.where(left, hi, mid)
        corners.extend(0.5 * (lo + hi))
    return corners


def _reinforced_half(h, n_points, *, concrete_strength, steel_strength, reinforcement_area,
                     axis_distance, width):
    """M ≥ 0 branch, pure compression → pure tension.

    Vertices equally spaced in scaled arc length, except that the corners of the curve
    (a bar layer reaching ±fyd, a change of pivot) are vertices too: a chord across a
    corner would err by O(spacing) instead of O(spacing²).
    """
    eps_c2, eps_cu2, _, _ = concrete_parameters(concrete_strength)
    strains = lambda q: _pivot_strains(q, h, h - axis_distance, eps_c2, eps_cu2)
    forces = lambda q: section_forces(
        *strains(q), h, concrete_strength=concrete_strength, steel_strength=steel_strength,
        reinforcement_area=reinforcement_area, axis_distance=axis_distance, width=width)
    p = np.linspace(0.0, 3.0, 20 * n_points)
    N, M = forces(p)
    s = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(N) / np.ptp(N), np.diff(M) / M.max()))])
    corners = [1.0, 2.0] + _yield_corners(strains, p, h, axis_distance, fyd(steel_strength) / ES)
    knots = np.unique(np.concatenate([[0.0, s[-1]], np.interp(corners, p, s)]))
    # intervals per knot span proportional to its length (largest remainder), ≥ 1 each
    share = np.diff(knots) / s[-1] * (n_points - len(knots))
    count = np.floor(share).astype(int)
    count[np.argsort(count - share)[: n_points - len(knots) - count.sum()]] += 1
    s_new = np.concatenate([np.linspace(a, b, c + 2)[:-1] for a, b, c in zip(knots[:-1], knots[1:], count)]
                           + [knots[-1:]])
    p_new = np.interp(s_new, s, p)
    for c in corners:  # exact corner parameters, not their round trip through s
        p_new[np.argmin(np.abs(p_new - c))] = c
    return forces(p_new[::-1])


def _plain_half(h, n_points, *, concrete_strength, width):
    """M ≥ 0 branch of (12.10), pure compression → origin.

    N / N_Rd(0) is sampled geometrically down to ``_U_MIN``: a chord between ratios
    u and r u errs by at most ((r − 1)/(r + 1))² along any ray, whatever u.
    """
    _, _, _, eta = concrete_parameters(concrete_strength)
    n0 = eta * fcd(concrete_strength, plain=True) * width * h
    u = np.concatenate([np.geomspace(1.0, _U_MIN, n_points - 1), [0.0]])
    return n0 * u, n0 * u * 0.5 * h * (1.0 - u)


def interaction_envelope(thickness: float, *, concrete_strength: float, steel_strength: float,
                         reinforcement_area: float, axis_distance: float, width: float = 1.0,
                         n_points: int = 501) -> tuple[np.ndarray, np.ndarray]:
    """Closed design N–M resistance curve of the section (module docstring for the laws).

    Parameters
    ----------
    thickness : float
        Section depth h (m).
    concrete_strength, steel_strength : float
        fck, fyk (Pa).
    reinforcement_area : float
        As per face (m² per metre of width); 0 gives the plain-concrete envelope.
    axis_distance : float
        d1 (m); used only when As > 0.
    width : float
        b (m).
    n_points : int
        Vertices on the M ≥ 0 branch, both ends included (≥ 20).

    Returns
    -------
    N, M : ndarray, shape (2 n_points - 1,)
        Vertices (N/m, N·m/m) counter-clockwise in the (N, M) plane from pure
        compression through M > 0, pure tension (the origin for plain concrete) and
        M < 0; the last point repeats the first.

    Raises
    ------
    ValueError
        If :func:`section_errors` reports any error, or ``n_points < 20``.
    """
    errors = section_errors(thickness, reinforcement_area, axis_distance,
                            concrete_strength=concrete_strength, steel_strength=steel_strength)
    if errors or n_points < 20:
        raise ValueError("; ".join(f"{f}: {r}" for f, r in errors) or "n_points: at least 20")
    if reinforcement_area > 0:
        N, M = _reinforced_half(thickness, n_points, concrete_strength=concrete_strength,
                                steel_strength=steel_strength, reinforcement_area=reinforcement_area,
                                axis_distance=axis_distance, width=width)
    else:
        N, M = _plain_half(thickness, n_points, concrete_strength=concrete_strength, width=width)
    M = np.abs(M)
    M[[0, -1]] = 0.0  # uniform strain: symmetric section, no moment (exactly)
    return np.concatenate([N, N[-2::-1]]), np.concatenate([M, -M[-2::-1]])


def utilization(N, M, envelope_N, envelope_M, *, chunk: int = 256) -> np.ndarray:
    """η = 1 / (load factor along the ray from the origin to the envelope).

    Parameters
    ----------
    N, M : array_like
        Design actions (N/m, N·m/m), broadcast together; any shape.
    envelope_N, envelope_M : array_like, shape (m,)
        Closed polygon (closed here if the last point differs from the first); the
        origin inside it or on its boundary.
    chunk : int
        Stations handled at once (memory ~ chunk · m).

    Returns
    -------
    ndarray
        η ≥ 0 (1), shape of ``N`` and ``M`` broadcast; 0 for (0, 0); ``inf`` where the
        ray leaves the envelope at once (no positive load factor is admissible).

    Notes
    -----
    Exact on the polygon: an edge i → i+1 is crossed by the ray's line when
    c_i = d × P_i and c_{i+1} change sign, at η = d × (P_{i+1} − P_i) / (P_i × P_{i+1});
    the first exit is the largest positive η. Edges on a line through the origin
    cannot be exits and are skipped. η is linear in (N, M).
    """
    N, M = np.broadcast_arrays(np.asarray(N, float), np.asarray(M, float))
    PN, PM = np.asarray(envelope_N, float), np.asarray(envelope_M, float)
    if PN[0] != PN[-1] or PM[0] != PM[-1]:
        PN, PM = np.append(PN, PN[0]), np.append(PM, PM[0])
    area = PN[:-1] * PM[1:] - PM[:-1] * PN[1:]          # P_i × P_{i+1}
    keep = area != 0.0
    a_n, a_m, b_n, b_m, area = PN[:-1][keep], PM[:-1][keep], PN[1:][keep], PM[1:][keep], area[keep]
    e_n, e_m = b_n - a_n, b_m - a_m
    dn, dm = N.ravel(), M.ravel()
    sector = _star_sectors(a_n, a_m, area) if keep.all() else None
    if sector is not None:  # each ray leaves through the one edge whose angular sector holds it
        i = sector(dn, dm)
        return ((dn * e_m[i] - dm * e_n[i]) / area[i]).reshape(N.shape)
    eta = np.empty(dn.shape)
    for k in range(0, dn.size, chunk):
        x, y = dn[k:k + chunk, None], dm[k:k + chunk, None]
        ca, cb = x * a_m - y * a_n, x * b_m - y * b_n
        # d × e, not cb − ca: no cancellation between the vertices' large cross products
        e = (x * e_m - y * e_n) / area
        hit = (np.sign(ca) * np.sign(cb) <= 0) & (e >= 0)
        best = np.max(np.where(hit, e, -1.0), axis=1, initial=-1.0)
        eta[k:k + chunk] = np.where(best < 0, np.inf, best)
    return eta.reshape(N.shape)


def _star_sectors(a_n, a_m, area):
    """Where the origin lies strictly inside a polygon that every ray from it leaves once (each
    edge seen turning counter-clockwise, ``P_i × P_{i+1} > 0``, once round): a function giving
    the edge each direction (N, M) leaves through, by the vertices' angles (O(log m) a station
    instead of O(m)); None for any other polygon (a plain section, whose envelope passes through
    the origin), which the general search serves."""
    if not (area > 0).all():
        return None
    start = np.arctan2(a_m[0], a_n[0])
    turn = np.arctan2(area, a_n * np.roll(a_n, -1) + a_m * np.roll(a_m, -1))  # each edge's angle, in (0, π)
    bounds = np.concatenate([[0.0], np.cumsum(turn)])
    if abs(bounds[-1] - 2.0 * np.pi) > 1e-9:
        return None

    def sector(n, m):
        rel = np.mod(np.arctan2(m, n) - start, 2.0 * np.pi)
        return np.clip(np.searchsorted(bounds, rel, side="right") - 1, 0, turn.size - 1)

    return sector


@lru_cache(maxsize=256)
def _cached_envelope(thickness: float, fck: float, fyk: float, area: float, axis: float):
    """:func:`interaction_envelope` once per section (sweeps check one section many times);
    the arrays are read-only because they are shared."""
    env = interaction_envelope(thickness, concrete_strength=fck, steel_strength=fyk,
                               reinforcement_area=area, axis_distance=axis)
    for a in env:
        a.flags.writeable = False
    return env


def _combinations(N, M, thickness: float, design):
    """Utilizations of (γF N, γF M) and (1.0 N, γF M), and the section's envelope."""
    env_N, env_M = _cached_envelope(float(thickness), float(design.concrete_strength),
                                    float(design.steel_strength), float(design.reinforcement_area),
                                    float(design.axis_distance))
    gamma = design.load_factor
    N, M = np.asarray(N, float), gamma * np.asarray(M, float)
    return utilization(gamma * N, M, env_N, env_M), utilization(N, M, env_N, env_M), env_N, env_M


def design_utilization(N, M, thickness: float, design) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Utilization of the characteristic forces N, M: the worse of (γF N, γF M) and (1.0 N, γF M)
    (SPEC §9.3: where bending governs, a lower thrust is unfavourable).

    Parameters
    ----------
    N, M : array_like
        Thrust (N/m) and moment (N·m/m) at the stations.
    thickness : float
        Section depth (m).
    design
        Has ``concrete_strength``, ``steel_strength`` (Pa), ``reinforcement_area``
        (m²/m per face), ``axis_distance`` (m) and ``load_factor`` γF (1).

    Returns
    -------
    eta : ndarray
        Utilization per station (1), ``inf`` for a failure at any load level.
    envelope_N, envelope_M : ndarray
        The closed envelope (:func:`interaction_envelope`).
    """
    full, favourable, env_N, env_M = _combinations(N, M, thickness, design)
    return np.maximum(full, favourable), env_N, env_M


def governing_thrust(N, M, thickness: float, design) -> np.ndarray:
    """N_Ed (N/m) of the governing combination of :func:`design_utilization` per station: γF N, or
    1.0 N where that gives the larger utilization."""
    full, favourable, _, _ = _combinations(N, M, thickness, design)
    N = np.asarray(N, float)
    return np.where(favourable > full, N, design.load_factor * N)


def joint_utilization(N, M, contact_height: float, design, *, width: float = 1.0) -> np.ndarray:
    """EN 1992-1-1 §12.6.1 (12.10) on a segmental lining's joints: the contact strip, ``a`` high, as a
    plain concrete section (no bar crosses a joint), at the joint's design thrust.

    The strip carries N_Ed on a rectangular block of η fcd,pl at its compressed edge, x = N_Ed /
    (η fcd,pl b) deep, so it holds the moment ``M_Rd = N_Ed (a - x) / 2`` (the (12.10) envelope at
    that thrust). The utilization is ``|M_Ed| / M_Rd`` (the moment at the joint's thrust, the way a
    joint is read: the thrust is what the ring carries, the moment what the joint's rotation leaves
    on it); ``inf`` when the strip cannot take the thrust at all (x ≥ a) or carries a moment
    without thrust. An open joint of the elastic contact solution bears on its strip's edge
    (|M| → N a/2, :attr:`solver.lining.joints.JointResults.eccentricity_ratio` → 1), so its
    utilization is a / (a - x): the stress block the edge needs is what the strip must give.

    Parameters: N, M (N/m, N·m/m) at the joints; design as :func:`design_utilization`.
    """
    gamma = design.load_factor
    n_ed = gamma * np.asarray(N, float)
    m_ed = gamma * np.abs(np.asarray(M, float))
    _, _, _, eta = concrete_parameters(design.concrete_strength)
    x = n_ed / (eta * fcd(design.concrete_strength, plain=True) * width)
    m_rd = n_ed * (contact_height - x) / 2.0
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.where(m_rd > 0, m_ed / np.where(m_rd > 0, m_rd, 1.0), np.inf)
    return np.where((n_ed == 0) & (m_ed == 0), 0.0, out)


def section_errors(thickness: float, reinforcement_area: float, axis_distance: float, *,
                   concrete_strength: float | None = None, steel_strength: float | None = None,
                   width: float = 1.0) -> list[tuple[str, str]]:
    """Why a section cannot be checked: ``[(field, reason), ...]``, empty when valid.

    ``axis_distance`` and ``steel_strength`` are checked only for a reinforced section
    (As > 0); the strengths only when given. Fields are named as in the case JSON.
    """
    errors: list[tuple[str, str]] = []
    if not (np.isfinite(thickness) and thickness > 0):
        return [("geometry.thickness", f"{thickness} m is not a positive section depth")]
    As = reinforcement_area
    if not (np.isfinite(As) and As >= 0):
        errors.append(("design.reinforcement_area", f"{As} m²/m per face must be a finite value ≥ 0"))
    elif 2 * As > MAX_STEEL_RATIO * width * thickness:
        errors.append(("design.reinforcement_area",
                       f"2 × {As} m²/m exceeds As,max = 0.04 Ac = {MAX_STEEL_RATIO * width * thickness:.4g} "
                       "m²/m (EN 1992-1-1 9.2.1.1(3))"))
    reinforced = np.isfinite(As) and As > 0
    if reinforced and not (np.isfinite(axis_distance) and 0 < axis_distance < thickness / 2):
        errors.append(("design.axis_distance",
                       f"{axis_distance} m puts the bars outside the section or past mid-depth "
                       f"(needs 0 < d1 < thickness/2 = {thickness / 2:.4g} m)"))
    if concrete_strength is not None and not (np.isfinite(concrete_strength)
                                              and 0 < concrete_strength <= MAX_FCK):
        errors.append(("design.concrete_strength",
                       f"fck = {concrete_strength} Pa is outside (0, 90 MPa], the range of EN 1992-1-1 Table 3.1"))
    if reinforced and steel_strength is not None and not (np.isfinite(steel_strength) and steel_strength > 0):
        errors.append(("design.steel_strength", f"fyk = {steel_strength} Pa must be positive"))
    return errors
