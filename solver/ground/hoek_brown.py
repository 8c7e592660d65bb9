"""Generalized Hoek–Brown return mapping (SPEC §9.1; Hoek, Carranza-Torres & Corkum 2002) at many
points at once: elastic–perfectly plastic, flow of Mohr–Coulomb type with a constant dilatancy ψ,
Rankine tension cut-off, on the three principal stresses of plane strain (σzz included).

Stresses are tension positive here (the criterion is usually written compression positive);
sorted principal stresses σ1 ≥ σ2 ≥ σ3. With ``x(σ) = s - m_b σ / σci`` (≥ 0 up to the apex
σ = s σci / m_b) the surfaces are:

- Hoek–Brown ``f_ij = (σi - σj) - σci x(σi)^a ≤ 0`` for the pair (most tensile i, most compressive
  j): (1, 3) *main*, joined at the *right edge* (σ1 = σ2) by (2, 3) and at the *left edge*
  (σ2 = σ3) by (1, 2); flow along ``b_ij = (1 + sin ψ) e_i - (1 - sin ψ) e_j`` (plastic potential
  of Mohr–Coulomb type);
- tension cut-off ``σi ≤ σt`` (associated, ``σt ≤ s σci / m_b``).

Returns (Koiter's rule, first admissible candidate, as :mod:`solver.mohr_coulomb`): with isotropic
elasticity every Hoek–Brown candidate moves the stress along a straight line of principal space
(the edge's two multipliers differ by a constant fixed by σ1 = σ2 or σ2 = σ3), so each is a scalar
equation in one multiplier, solved by Newton in ``t = x^a`` (the equation is concave and decreasing
in t, so Newton converges from any start, without the infinite slope of x^a at the apex). With the
cut-off of σi active, σi = σt and every surface f_i· is a plane: those candidates are linear. The
in-plane principal directions of the trial stress are kept (isotropy).
"""
from __future__ import annotations

import itertools
import math
from typing import NamedTuple

import numpy as np
from numba import njit

from .principal import descending, extremes, from_principal, order_of, principal, put_back, sorted_at, unsorted
from .tangent import active_set_jacobian, elastic_matrix, full_tangent, unsort

#: Relative tolerance of "on or inside a surface" (to the stresses' scale).
YIELD_TOL = 1e-9
#: Newton's stop: the step in t = x^a relative to t (and to s^a), and the iterations allowed.
NEWTON_TOL = 1e-14
NEWTON_ITERATIONS = 60


def constants(gsi, mi, disturbance):
    """Hoek–Brown constants ``(m_b, s, a)`` of the rock mass (Hoek, Carranza-Torres & Corkum 2002):
    m_b = m_i exp((GSI - 100)/(28 - 14 D)), s = exp((GSI - 100)/(9 - 3 D)),
    a = ½ + (exp(-GSI/15) - exp(-20/3))/6. Scalars or arrays."""
    gsi, mi, d = (np.asarray(v, dtype=float) for v in (gsi, mi, disturbance))
    mb = mi * np.exp((gsi - 100.0) / (28.0 - 14.0 * d))
    s = np.exp((gsi - 100.0) / (9.0 - 3.0 * d))
    a = 0.5 + (np.exp(-gsi / 15.0) - np.exp(-20.0 / 3.0)) / 6.0
    return mb, s, a


def parameter_errors(ucs, gsi, mi, disturbance, dilatancy=0.0, tensile_strength=None) -> dict[str, str]:
    """Field → reason for each bad Hoek–Brown input (empty when all are admissible): ``ucs`` > 0 and
    finite (Pa), 10 ≤ ``gsi`` ≤ 100, 1 ≤ ``mi`` ≤ 50, 0 ≤ ``disturbance`` ≤ 1, 0 ≤ ``dilatancy`` < 90
    (deg), 0 ≤ ``tensile_strength`` ≤ s σci / m_b (the criterion's apex; None: that default)."""
    errors: dict[str, str] = {}

    def bad(value) -> bool:
        return not isinstance(value, (int, float)) or isinstance(value, bool) or not math.isfinite(value)

    if bad(ucs) or ucs <= 0:
        errors["ucs"] = "must be a finite number > 0 (Pa)"
    if bad(gsi) or not 10 <= gsi <= 100:
        errors["gsi"] = "must be between 10 and 100"
    if bad(mi) or not 1 <= mi <= 50:
        errors["mi"] = "must be between 1 and 50"
    if bad(disturbance) or not 0 <= disturbance <= 1:
        errors["disturbance"] = "must be between 0 and 1"
    if bad(dilatancy) or not 0 <= dilatancy < 90:
        errors["dilatancy"] = "must be between 0 and 90 degrees (90 excluded)"
    if tensile_strength is not None:
        if bad(tensile_strength) or tensile_strength < 0:
            errors["tensile_strength"] = "must be a finite number ≥ 0 (Pa)"
        elif not errors.keys() & {"ucs", "gsi", "mi", "disturbance"}:
            apex = default_tensile_strength(ucs, gsi, mi, disturbance)
            if tensile_strength > apex * (1 + 1e-12):
                errors["tensile_strength"] = f"must be at most s·ucs/m_b = {apex:.6g} Pa (the criterion's apex)"
    return errors


def default_tensile_strength(ucs, gsi, mi, disturbance):
    """The criterion's apex s σci / m_b (Pa): the default tension cut-off."""
    mb, s, _ = constants(gsi, mi, disturbance)
    return s * np.asarray(ucs, dtype=float) / mb


def hoek_brown_excess(s_major: float, s_minor: float, ucs: float, gsi: float, mi: float, disturbance: float,
                      tensile_strength: float | None = None) -> float:
    """How far a state with major and minor principal stresses (Pa, compression positive) lies outside
    the Hoek–Brown surface with its tension cut-off (Pa; ≤ 0 inside), as
    :func:`solver.strata.mohr_coulomb_excess` (for the geostatic check)."""
    mb, s, a = (float(v) for v in constants(gsi, mi, disturbance))
    apex = s * ucs / mb
    t = apex if tensile_strength is None else min(tensile_strength, apex)
    shear = (s_major - s_minor) - ucs * max(mb * s_minor / ucs + s, 0.0) ** a
    return float(max(shear, -s_minor - t))


class HBMaterial(NamedTuple):
    """Per-point constants of the return (arrays (n,)): Lamé's λ, μ (Pa), σci (Pa), m_b, s, a,
    sin ψ and the tension cut-off σt (Pa, ≤ s σci / m_b). Built with :meth:`of`, or directly
    (tests set a = 1 to meet Mohr–Coulomb)."""

    lam: np.ndarray
    mu: np.ndarray
    ucs: np.ndarray
    mb: np.ndarray
    s: np.ndarray
    a: np.ndarray
    sin_psi: np.ndarray
    tensile: np.ndarray

    @classmethod
    def of(cls, n: int, lam, mu, ucs, gsi, mi, disturbance, dilatancy, tensile=None) -> "HBMaterial":
        """From the SPEC's fields (scalars or (n,) arrays; angles in degrees; ``tensile`` None or
        NaN: the apex s σci / m_b)."""
        # (writable copies: the compiled return is specialized on its arrays' flags, one kind)
        bc = lambda v: np.array(np.broadcast_to(np.asarray(v, dtype=float), (n,)))  # noqa: E731
        mb, s, a = constants(bc(gsi), bc(mi), bc(disturbance))
        ucs = bc(ucs)
        apex = s * ucs / mb
        t = apex if tensile is None else np.where(np.isnan(bc(tensile)), apex, np.minimum(bc(tensile), apex))
        return cls(bc(lam), bc(mu), ucs, mb, s, a, np.sin(np.radians(bc(dilatancy))), t)

    def at(self, index: np.ndarray) -> "HBMaterial":
        return HBMaterial(*(v[index] for v in self))


def strength(sigma, mat: HBMaterial) -> np.ndarray:
    """σci x(σ)^a (Pa): the largest σi - σj the criterion allows at σi = ``sigma`` (0 beyond the apex)."""
    x = np.maximum(mat.s - mat.mb * sigma / mat.ucs, 0.0)
    return mat.ucs * x**mat.a


def yield_values(s: np.ndarray, mat: HBMaterial) -> np.ndarray:
    """(6, n) values of f13, f23, f12 and the three tension cut-offs at sorted principal stresses
    ``s`` (3, n); ≤ 0 inside. (A stress beyond the apex is outside: x clamped at 0.)"""
    s1s, s2s = strength(s[0], mat), strength(s[1], mat)
    return np.vstack([s[0] - s[2] - s1s, s[1] - s[2] - s2s, s[0] - s[1] - s1s, s - mat.tensile])


def return_map(trial: np.ndarray, lam, mu, ucs, gsi, mi, disturbance, dilatancy, tensile=None,
               flag_tolerance: float = YIELD_TOL):
    """Return trial stresses (4, n) to the Hoek–Brown surface with tension cut-off (arguments as
    :meth:`HBMaterial.of`); see :func:`return_stress`."""
    return return_stress(trial, HBMaterial.of(trial.shape[1], lam, mu, ucs, gsi, mi, disturbance, dilatancy,
                                              tensile), flag_tolerance)


def return_stress(trial: np.ndarray, mat: HBMaterial, flag_tolerance: float = YIELD_TOL):
    """Return trial stresses (4, n) = (xx, yy, xy, zz), tension positive, to the surface.

    Returns ``(stress (4, n), plastic_strain (3, n), at_yield (n,) bool)`` as
    :func:`solver.mohr_coulomb.return_stress`: the plastic strain increment Σ Δγ b in the trial's
    principal axes (in-plane major, in-plane minor, zz); points inside stay exactly as they are;
    ``at_yield`` flags the points within ``flag_tolerance`` (relative) of the surface or outside.
    Raises ``ArithmeticError`` if some point finds no admissible return.
    """
    stress, dep, at_yield, _ = _stress_and_jacobian(trial, mat, flag_tolerance, jacobian=False)
    return stress, dep, at_yield


def consistent_tangent(trial: np.ndarray, mat: HBMaterial, flag_tolerance: float = YIELD_TOL):
    """The return (as :func:`return_stress`) and its algorithmic tangent (n, 4, 4): strain
    increments (dεxx, dεyy, dγxy, dεzz), engineering shear γxy = 2 εxy, to stress increments
    (dσxx, dσyy, dσxy, dσzz), the spin of the principal directions included
    (:mod:`solver.ground.tangent`); the elastic matrix at points inside.

    Returns ``(stress, plastic_strain, at_yield, tangent)``.
    """
    stress, dep, at_yield, tangent = _stress_and_jacobian(trial, mat, flag_tolerance, jacobian=True)
    return stress, dep, at_yield, tangent


def _stress_and_jacobian(trial, mat, flag_tolerance, jacobian: bool):
    n = trial.shape[1]
    stress, dep, ordered = np.empty((4, n)), np.empty((3, n)), np.empty((3, n))
    at_yield, state, scale = np.empty(n, bool), np.empty(n, np.int64), np.empty(n)
    _main_returns(np.ascontiguousarray(trial, float), *mat, float(flag_tolerance), stress, dep, at_yield, state,
                  scale, ordered)
    rest = np.flatnonzero(state == REST)
    tangent = elastic_matrix(mat.lam, mat.mu) if jacobian else None
    if rest.size:
        m = mat.at(rest)
        ret, dep_t, J = _return(trial[:, rest], m, scale[rest], jacobian)
        stress[:, rest], dep[:, rest] = ret, dep_t
        if jacobian:
            tangent[rest] = full_tangent(trial[:, rest], ret, J, m.lam, m.mu, scale[rest])
    main = np.flatnonzero(state == MAIN)
    if jacobian and main.size:
        m = mat.at(main)
        major, minor, _, szz = principal(trial[:, main])
        J = active_set_jacobian(_hb_normal(0, 2, ordered[:, main].T, m)[:, None], _flow(0, 2, m.sin_psi)[:, None],
                                m.lam, m.mu)
        J = unsort(J, order_of(descending(major, minor, szz)[1]))
        tangent[main] = full_tangent(trial[:, main], stress[:, main], J, m.lam, m.mu, scale[main])
    return stress, dep, at_yield, tangent


#: :func:`_main_returns`' ``state`` of a point: inside, returned onto f13 alone, outside and left to the other
#: candidates (:func:`_return`)
INSIDE, MAIN, REST = -1, 0, 1


@njit(cache=True)
def _strength(sigma, ucs, mb, s, a):
    """:func:`strength` at one point."""
    return ucs * max(s - mb * sigma / ucs, 0.0) ** a


@njit(cache=True)
def _main_returns(trial, lam, mu, ucs, mb, s, a, sin_psi, tensile, flag, stress, dep, at_yield, state, scale,
                  ordered):
    """Every point of ``trial`` (4, n) screened on its largest and least principal stresses and, where outside,
    returned onto f13 alone when that return is admissible (Koiter's conditions); compiled, one pass. Fills
    ``stress`` (4, n), ``dep`` (3, n) (principal plastic strain increments in the trial's axes), ``at_yield``,
    ``state`` (:data:`INSIDE`, :data:`MAIN`, :data:`REST`), the stress scale ``max(|σ1|, |σ3|, σci s^a, 1 Pa)``
    (where the point is near yield or outside) and, where returned, the sorted principal stresses ``ordered``
    (3, n)."""
    st, ep = np.empty(3), np.empty(3)
    for i in range(trial.shape[1]):
        s1, s3 = extremes(trial, i)
        u, m_b, s_, a_ = ucs[i], mb[i], s[i], a[i]
        f = max(s1 - s3 - _strength(s1, u, m_b, s_, a_), s1 - tensile[i])
        for x in range(4):
            stress[x, i] = trial[x, i]
        dep[0, i] = dep[1, i] = dep[2, i] = 0.0
        state[i] = INSIDE
        sc = max(max(s1, -s3), 1.0)
        if f <= -flag * max(sc, u * max(s_, 1.0)):  # well inside, whatever σci s^a ≤ σci max(s, 1) (a ≤ 1)
            at_yield[i] = False
            continue
        scale[i] = sc = max(sc, u * s_ ** a_)
        at_yield[i] = f > -flag * sc
        if not f > YIELD_TOL * sc:
            continue
        at_yield[i] = True
        state[i] = REST
        top, middle, c2, s2 = sorted_at(trial, i, st)
        sq = sin_psi[i]
        b0, b2 = 1.0 + sq, -(1.0 - sq)  # f13's flow b13 and D b13
        d0, d1, d2 = 2.0 * lam[i] * sq + 2.0 * mu[i] * b0, 2.0 * lam[i] * sq, 2.0 * lam[i] * sq + 2.0 * mu[i] * b2
        gam = _line_root(st[0] - st[2], d0 - d2, st[0], d0, u, m_b, s_, a_)
        r0, r1, r2 = st[0] - gam * d0, st[1] - gam * d1, st[2] - gam * d2
        t, lim = tensile[i], YIELD_TOL * sc
        if not (gam >= -YIELD_TOL and np.isfinite(gam) and np.isfinite(r0) and np.isfinite(r1) and np.isfinite(r2)
                and r0 >= r1 - lim and r1 >= r2 - lim and max(r0, max(r1, r2)) - t <= lim
                and r0 - r2 - _strength(r0, u, m_b, s_, a_) <= lim and r1 - r2 - _strength(r1, u, m_b, s_, a_) <= lim
                and r0 - r1 - _strength(r0, u, m_b, s_, a_) <= lim):
            continue
        state[i] = MAIN
        ordered[0, i], ordered[1, i], ordered[2, i] = r0, r1, r2
        ep[0], ep[1], ep[2] = gam * b0, 0.0, gam * b2
        put_back(i, top, middle, c2, s2, ordered[:, i], ep, stress, dep)


@njit(cache=True)
def _line_root(A, B, P, Q, ucs, mb, s, a):
    """The multiplier γ where the line σi = P - Q γ, σi - σj = A - B γ meets the surface
    ``σi - σj = σci x(σi)^a`` (B > 0, Q > 0), by Newton in t = x^a ∈ [0, ∞): with
    γ(t) = (P - σci (s - t^(1/a)) / m_b) / Q the equation h(t) = A - B γ(t) - σci t = 0 is concave
    and decreasing in t, so Newton converges from any start (from the right of the root after
    at most one step, monotonically). NaN where no root with x ≥ 0 exists."""
    inv_a = 1.0 / a
    c0 = (P - ucs * s / mb) / Q  # γ at the apex, t = 0
    k = ucs / (mb * Q)  # γ(t) = c0 + k t^(1/a)
    if not A - B * c0 >= 0.0:  # h(0) < 0: no root in t ≥ 0
        return np.nan
    t = max(s - mb * P / ucs, 0.0) ** a  # at γ = 0
    tref, bk = max(s ** a, 1e-300), B * k
    for _ in range(NEWTON_ITERATIONS):
        power = t ** inv_a  # t^(1/a); its derivative (1/a) t^(1/a - 1) from it (0 at t = 0: 1/a > 1)
        slope = power / t if t > 0.0 else 0.0
        h = A - B * c0 - bk * power - ucs * t
        new = max(t + h / (bk * inv_a * slope + ucs), 0.0)
        done = abs(new - t) <= NEWTON_TOL * max(new, tref)
        t = new
        if done:
            break
    return c0 + k * t ** inv_a


@njit(cache=True)
def _line_roots(A, B, P, Q, ucs, mb, s, a):
    """:func:`_line_root` at every point (arrays (m,))."""
    out = np.empty(A.size)
    for i in range(A.size):
        out[i] = _line_root(A[i], B[i], P[i], Q[i], ucs[i], mb[i], s[i], a[i])
    return out


def _flow(i: int, j: int, sq: np.ndarray) -> np.ndarray:
    """Flow directions b_ij (m, 3) = (1 + sin ψ) e_i - (1 - sin ψ) e_j."""
    b = np.zeros((sq.size, 3))
    b[:, i], b[:, j] = 1.0 + sq, -(1.0 - sq)
    return b


def _return(trial, m: HBMaterial, scale, jacobian: bool):
    """The multi-surface return of trial states (4, k) that lie outside and whose return onto f13 alone
    is not admissible (:func:`_main_returns`): stress (4, k), principal plastic strain increments (3, k) in
    the trial's axes and, if asked, the principal Jacobian (k, 3, 3) in those axes."""
    k = trial.shape[1]
    major, minor, direction, szz = principal(trial)
    st, perm = descending(major, minor, szz)
    st = st.T  # (k, 3) sorted σ1 ≥ σ2 ≥ σ3
    lam, mu, sq = m.lam, m.mu, m.sin_psi
    res = np.full((k, 3), np.nan)
    strain = np.zeros((k, 3))
    J = np.zeros((k, 3, 3)) if jacobian else None
    left = np.ones(k, bool)

    def Dv(b):  # isotropic elasticity on principal vectors (P, 3)
        return lam_p[:, None] * b.sum(axis=1, keepdims=True) + 2.0 * mu_p[:, None] * b

    # the Hoek–Brown edges: right (1, 3) + (2, 3), σ1 = σ2; left (1, 3) + (1, 2), σ2 = σ3. Their
    # multipliers are γ + δ (on (1, 3)) and γ.
    for cand in ("right", "left"):
        p = np.flatnonzero(left)
        if p.size == 0:
            break
        lam_p, mu_p, sq_p, mp, tr = lam[p], mu[p], sq[p], m.at(p), st[p]
        b13 = _flow(0, 2, sq_p)
        if cand == "right":
            other = _flow(1, 2, sq_p)
            delta = (tr[:, 0] - tr[:, 1]) / (2.0 * mu_p * (1.0 + sq_p))
            start, d = tr - delta[:, None] * Dv(b13), Dv(b13 + other)
        else:
            other = _flow(0, 1, sq_p)
            delta = (tr[:, 1] - tr[:, 2]) / (2.0 * mu_p * (1.0 - sq_p))
            start, d = tr - delta[:, None] * Dv(b13), Dv(b13 + other)
        gam = _line_roots(start[:, 0] - start[:, 2], d[:, 0] - d[:, 2], start[:, 0], d[:, 0], mp.ucs, mp.mb, mp.s,
                          mp.a)
        with np.errstate(invalid="ignore"):
            sig = start - gam[:, None] * d
        sig[:, 1] = sig[:, 0] if cand == "right" else sig[:, 2]  # exactly on the edge (rounding apart)
        gams = np.stack([gam + delta, gam], axis=1)
        ok = _admissible(gams, sig, mp, scale[p])
        hit = p[ok]
        res[hit] = sig[ok]
        strain[hit] = (gam + delta)[ok, None] * b13[ok] + gam[ok, None] * other[ok]
        if jacobian and hit.size:
            edge = _hb_normal(1, 2, sig[ok], mp.at(ok)) if cand == "right" else _hb_normal(0, 1, sig[ok], mp.at(ok))
            normals = np.stack([_hb_normal(0, 2, sig[ok], mp.at(ok)), edge], axis=1)
            J[hit] = active_set_jacobian(normals, np.stack([b13[ok], other[ok]], axis=1), lam_p[ok], mu_p[ok])
        left[hit] = False
    if left.any():
        _linear_returns(st, m, scale, left, res, strain, J)
    if left.any():
        _corner_returns(st, m, scale, left, res, strain, J)
    if left.any():
        raise ArithmeticError(f"Hoek-Brown return mapping found no admissible stress at {left.sum()} points")
    back = unsorted(res.T, perm)
    if jacobian:
        J = unsort(J, order_of(perm))
    return from_principal(back[0], back[1], direction, back[2]), unsorted(strain.T, perm), J


def _hb_normal(i: int, j: int, sig, m: HBMaterial) -> np.ndarray:
    """The normal of f_ij at sorted stresses ``sig`` (P, 3), scaled to stay finite at the apex:
    e_i - w e_j with w = 1 / (1 + a m_b x^(a-1)) = x^(1-a) / (x^(1-a) + a m_b)."""
    x = np.maximum(m.s - m.mb * sig[:, i] / m.ucs, 0.0)
    xa = x ** (1.0 - m.a)
    n = np.zeros_like(sig)
    n[:, i] = 1.0
    n[:, j] = -xa / (xa + m.a * m.mb)
    return n


#: Candidate sets with the cut-off active (0 f13, 1 f23, 2 f12, 3-5 cut-offs of σ1, σ2, σ3): with
#: σi = σt every f_i· is the plane σi - σj = σci x(σt)^a, so these returns are linear. f23 needs
#: σ2's cut-off (else it is not a plane), and is active only with f13 (f23 ≤ f13 when σ1 ≥ σ2).
LINEAR_CANDIDATES = tuple(
    tuple(sorted(f + cut))
    for cut in ((3,), (3, 4), (3, 4, 5))
    for k in range(4) for f in itertools.combinations((0, 1, 2), k)
    if (1 not in f or 4 in cut) and (1 not in f or 0 in f) and len(f) + len(cut) <= 4)
_PAIRS = ((0, 2), (1, 2), (0, 1))


def _linear_returns(st, m: HBMaterial, scale, left, res, strain, J):
    """The candidates with the cut-off active, at the points ``left`` (updated in place)."""
    for cand in LINEAR_CANDIDATES:
        p = np.flatnonzero(left)
        if p.size == 0:
            return
        mp, sr = m.at(p), st[p]
        lam, mu, sq = mp.lam, mp.mu, mp.sin_psi
        A, B, kc = [], [], []
        st_t = _cutoff_strength(mp)[1]
        for c in cand:
            a = np.zeros((p.size, 3))
            if c < 3:
                i, j = _PAIRS[c]
                a[:, i], a[:, j] = 1.0, -1.0
                A.append(a)
                B.append(_flow(i, j, sq))
                kc.append(st_t)
            else:
                a[:, c - 3] = 1.0
                A.append(a)
                B.append(a)
                kc.append(mp.tensile)
        a, b, kc = np.stack(A, axis=1), np.stack(B, axis=1), np.stack(kc, axis=1)  # (P, k, 3), (P, k)
        Db = lam[:, None, None] * b.sum(axis=2, keepdims=True) + 2.0 * mu[:, None, None] * b
        M = np.einsum("pjx,plx->pjl", a, Db)
        rhs = np.einsum("pjx,px->pj", a, sr) - kc
        with np.errstate(all="ignore"):
            try:
                gam = np.linalg.solve(M, rhs[..., None])[..., 0]
            except np.linalg.LinAlgError:
                continue
        sig = sr - np.einsum("pl,plx->px", gam, Db)
        ok = _admissible(gam, sig, mp, scale[p])
        hit = p[ok]
        res[hit] = sig[ok]
        strain[hit] = np.einsum("pl,plx->px", gam[ok], b[ok])
        if J is not None and hit.size:
            J[hit] = active_set_jacobian(a[ok], b[ok], lam[ok], mu[ok])
        left[hit] = False


def _cutoff_strength(m: HBMaterial):
    """Whether the cut-off is at the apex and σci x(σt)^a: the apex judged on x and its strength taken
    as exactly 0, since x^a magnifies the rounding of x = s - m_b σt/σci there (1e-20 of s gives
    σci 1e-10, mPa)."""
    at_apex = m.s - m.mb * m.tensile / m.ucs <= 1e-12 * m.s
    return at_apex, np.where(at_apex, 0.0, strength(m.tensile, m))


def _corner_returns(st, m: HBMaterial, scale, left, res, strain, J):
    """Returns to the corner σ1 = σ2 = σt, σ3 = σt - σci x(σt)^a (the apex when the cut-off is
    there), where more surfaces meet than principal space has dimensions (the cut-offs of σ1 and
    σ2, f13 and f23; at the apex all six), so no linear candidate holds it: the plastic strain is
    D⁻¹(τ - σ_corner) whatever the multipliers, admissible if it lies in the cone of the active
    flow directions (some three of them with non-negative multipliers)."""
    p = np.flatnonzero(left)
    mp, sr = m.at(p), st[p]
    lam, mu, sq = mp.lam, mp.mu, mp.sin_psi
    at_apex, gap = _cutoff_strength(mp)  # b12 and e3 join at the apex
    corner = np.stack([mp.tensile, mp.tensile, mp.tensile - gap], axis=1)
    drop = sr - corner  # D Δεp
    dep = (drop - (lam / (3.0 * lam + 2.0 * mu))[:, None] * drop.sum(axis=1, keepdims=True)) / (2.0 * mu[:, None])
    e = np.eye(3)
    flows = np.stack([_flow(0, 2, sq), _flow(1, 2, sq), *(np.broadcast_to(v, (p.size, 3)) for v in e[:2]),
                      _flow(0, 1, sq), np.broadcast_to(e[2], (p.size, 3))], axis=1)  # (P, 6, 3)
    found = np.zeros(p.size, bool)
    for triple in itertools.combinations(range(6), 3):
        Bt = np.swapaxes(flows[:, list(triple)], 1, 2)  # (P, 3, 3), columns b_l
        good = np.abs(np.linalg.det(Bt)) > 1e-9  # (b13, b23, b12 are dependent at ψ = 0)
        if max(triple) >= 4:
            good &= at_apex
        good &= ~found
        if not good.any():
            continue
        gam = np.linalg.solve(Bt[good], dep[good][..., None])[..., 0]
        cone = np.all(gam >= -YIELD_TOL * np.abs(gam).max(axis=1, keepdims=True), axis=1)
        found[np.flatnonzero(good)[cone]] = True
    hit = p[found]
    res[hit] = corner[found]
    strain[hit] = dep[found]
    if J is not None:
        J[hit] = 0.0
    left[hit] = False


def _admissible(gam, sig, m: HBMaterial, scale) -> np.ndarray:
    """Koiter's conditions of candidate returns: multipliers ``gam`` (P, k) non-negative, stresses
    ``sig`` (P, 3) on or inside every surface, in the principal order, finite."""
    with np.errstate(invalid="ignore"):
        fv = yield_values(sig.T, m)
        return (np.all(gam >= -YIELD_TOL, axis=1) & np.all(fv <= YIELD_TOL * scale, axis=0)
                & (sig[:, 0] >= sig[:, 1] - YIELD_TOL * scale) & (sig[:, 1] >= sig[:, 2] - YIELD_TOL * scale)
                & np.all(np.isfinite(sig), axis=1) & np.all(np.isfinite(gam), axis=1))
