"""Mohr–Coulomb return mapping (SPEC §1.5) at many points at once: elastic–perfectly plastic,
non-associated flow (dilatancy ψ ≤ φ), Rankine tension cut-off, on the three principal
stresses of plane strain (σzz included).

Stresses are tension positive; sorted principal stresses σ1 ≥ σ2 ≥ σ3. The surfaces:

- Mohr–Coulomb planes ``f = (σi - σj) + (σi + σj) sin φ - 2 c cos φ ≤ 0``; with sorted stresses
  the governing one is (1, 3) (*main*), and (2, 3) (*right edge*, σ1 = σ2) or (1, 2) (*left
  edge*, σ2 = σ3) join it at the edges; flow along ``g`` with ψ in place of φ;
- tension cut-off ``σi ≤ σt`` (associated).

The return is a multi-surface one: for a candidate set of active surfaces the plastic
multipliers solve ``a_j · (s - D Σ_l Δγ_l b_l) = k_j`` (j in the set; ``a`` the surface's
normal, ``b`` its flow direction, ``D`` the isotropic elasticity in principal axes); the
first candidate whose multipliers are non-negative, whose stress satisfies every surface
and keeps the principal order is the answer (Koiter's rule). Each candidate is exact (the
surfaces are planes in principal space), so the answer is exact: edges and apex included.
The in-plane principal directions of the trial stress are kept (isotropy).
"""
from __future__ import annotations

import itertools
from typing import NamedTuple

import numpy as np

from .principal import descending, from_principal, order_of, principal, unsorted
from .tangent import active_set_jacobian, full_tangent, unsort

#: Relative tolerance of "on or inside a surface" (to the stresses' scale).
YIELD_TOL = 1e-9


def yield_values(s: np.ndarray, cohesion, sin_phi, cos_phi, tensile) -> np.ndarray:
    """(4, n) values of the main Mohr–Coulomb plane and the three tension cut-offs at sorted
    principal stresses ``s`` (3, n); ≤ 0 inside."""
    main = (s[0] - s[2]) + (s[0] + s[2]) * sin_phi - 2.0 * cohesion * cos_phi
    return np.vstack([main, s - tensile])


def _surfaces(sin_phi, sin_psi):
    """Normals ``a`` and flow directions ``b`` (3,) of: 0 main, 1 right edge, 2 left edge,
    3-5 tension cut-offs of σ1, σ2, σ3; and which constant each compares with."""
    def plane(i, j, s):
        v = np.zeros(3)
        v[i], v[j] = 1.0 + s, -(1.0 - s)
        return v

    a = [plane(0, 2, sin_phi), plane(1, 2, sin_phi), plane(0, 1, sin_phi), *np.eye(3)]
    b = [plane(0, 2, sin_psi), plane(1, 2, sin_psi), plane(0, 1, sin_psi), *np.eye(3)]
    return np.array(a), np.array(b)


#: Candidate active sets, tried in order, fewest surfaces first (indices: 0 main, 1 right edge,
#: 2 left edge, 3-5 tension cut-offs of σ1, σ2, σ3); sets whose system is singular (the three
#: Mohr–Coulomb planes together) are skipped.
CANDIDATES = tuple(c for k in (1, 2, 3, 4) for c in itertools.combinations(range(6), k))


def return_map(trial: np.ndarray, lam, mu, cohesion, friction_angle, dilatancy, tensile,
               flag_tolerance: float = YIELD_TOL):
    """Return trial stresses (4, n) to the Mohr–Coulomb surface with tension cut-off.

    ``lam``, ``mu`` (Lamé, Pa), ``cohesion`` (Pa), angles (deg), ``tensile`` (Pa): scalars or
    (n,) arrays. Returns ``(stress (4, n), plastic_strain (3, n) in principal axes (the
    increment Σ Δγ b), at_yield (n,) bool)``. Points whose trial stress is inside stay as
    they are; ``at_yield`` flags the points whose trial lies within ``flag_tolerance`` (relative)
    of the surface or outside it. Raises ``ArithmeticError`` if some point finds no admissible
    return.
    """
    return return_stress(trial, Material.of(trial.shape[1], lam, mu, cohesion, friction_angle, dilatancy, tensile),
                         flag_tolerance)


class Material(NamedTuple):
    """Per-point constants of the return (arrays (n,)): Lamé's λ, μ (Pa), cohesion c (Pa),
    sin φ, cos φ, sin ψ and the tension cut-off σt (Pa)."""

    lam: np.ndarray
    mu: np.ndarray
    c: np.ndarray
    sin_phi: np.ndarray
    cos_phi: np.ndarray
    sin_psi: np.ndarray
    tensile: np.ndarray

    @classmethod
    def of(cls, n: int, lam, mu, cohesion, friction_angle, dilatancy, tensile) -> "Material":
        bc = lambda v: np.ascontiguousarray(np.broadcast_to(np.asarray(v, dtype=float), (n,)))  # noqa: E731
        phi, psi = np.radians(bc(friction_angle)), np.radians(bc(dilatancy))
        return cls(bc(lam), bc(mu), bc(cohesion), np.sin(phi), np.cos(phi), np.sin(psi), bc(tensile))

    def at(self, index: np.ndarray) -> "Material":
        return Material(*(v[index] for v in self))


def return_stress(trial: np.ndarray, mat: Material, flag_tolerance: float = YIELD_TOL):
    """:func:`return_map` with the material's constants prepared once (:class:`Material`)."""
    return _stress(trial, mat, flag_tolerance, False)[:3]


def consistent_tangent(trial: np.ndarray, mat: Material, flag_tolerance: float = YIELD_TOL,
                       frozen: np.ndarray | None = None):
    """The return (as :func:`return_stress`) and its algorithmic tangent at the returned points:
    ``(stress, plastic_strain, at_yield, returned (r,) indices, tangent (r, 4, 4))``, the tangent
    mapping strain increments (dεxx, dεyy, dγxy, dεzz) to stress increments (the layout of
    :mod:`.tangent`; the elastic matrix everywhere else). Each returned point's principal Jacobian
    is that of its active set (:func:`.tangent.active_set_jacobian`: one plane, an edge's two, a
    point of principal space for three or more), in the trial's axes, with the spin of its in-plane
    directions (:func:`.tangent.full_tangent`).

    ``frozen`` (n,) bool, if given, fixes which points flow: the others stay elastic even outside
    the surface, and those inside are returned onto the main plane all the same (a negative
    multiplier). The return is then smooth in the trial (an active-set step of the equilibrium
    iteration, :mod:`solver.stages.newton`); ``at_yield`` flags the points outside."""
    return _stress(trial, mat, flag_tolerance, True, frozen)


def _stress(trial: np.ndarray, mat: Material, flag_tolerance: float, tangent: bool, frozen=None):
    n = trial.shape[1]
    c, sp, cp, t = mat.c, mat.sin_phi, mat.cos_phi, mat.tensile
    # a cheap screen of every point: the largest and least principal stresses without sorting
    # or directions (most of the ground is elastic at any iterate)
    # (in place: this runs at every point of every iterate)
    sxx, syy, sxy, szz = trial
    mid = sxx + syy
    mid *= 0.5
    rad = sxx - syy
    rad *= 0.5
    rad *= rad
    rad += sxy * sxy
    np.sqrt(rad, out=rad)
    s1 = mid + rad
    np.maximum(s1, szz, out=s1)
    s3 = mid
    s3 -= rad
    np.minimum(s3, szz, out=s3)
    scale = np.maximum(s1, -s3)  # max(|σ1|, |σ3|), as σ1 ≥ σ3
    np.maximum(scale, c, out=scale)
    np.maximum(scale, 1.0, out=scale)
    fmax = s1 - s3
    s3 += s1
    s3 *= sp
    fmax += s3
    fmax -= 2.0 * c * cp
    s1 -= t
    np.maximum(fmax, s1, out=fmax)
    at_yield = fmax > -flag_tolerance * scale
    outside = fmax > YIELD_TOL * scale
    forced = np.zeros(0, np.int64)
    if frozen is not None:
        forced = np.flatnonzero(frozen & ~outside)
        outside &= frozen
    todo = np.flatnonzero(outside)
    stress = np.array(trial, dtype=float)  # a state inside stays exactly as it was
    dep = np.zeros((3, n))
    C = np.zeros((0, 4, 4))
    if todo.size:
        m = mat.at(todo)
        ret, dep_t, active = _return(trial[:, todo], m.lam, m.mu, m.c, m.sin_phi, m.cos_phi, m.sin_psi,
                                     m.tensile, scale[todo])
        stress[:, todo], dep[:, todo] = ret, dep_t
        at_yield[todo] = True
        if tangent:
            C = _tangent(trial[:, todo], ret, active, m, scale[todo])
    if forced.size:
        m = mat.at(forced)
        ret, dep_f = _main_plane(trial[:, forced], m)
        stress[:, forced], dep[:, forced] = ret, dep_f
        if tangent:
            C = np.concatenate([C, _tangent(trial[:, forced], ret, np.zeros(forced.size, np.int64), m,
                                            scale[forced])])
        todo = np.concatenate([todo, forced])
    if tangent:
        return stress, dep, at_yield, todo, C
    return stress, dep, at_yield


def _main_plane(trial, m: Material):
    """The return onto the main plane (σ1, σ3) whatever the multiplier's sign (a frozen active
    set): stress (4, r) and principal plastic strain increments (3, r) in the trial's axes."""
    major, minor, direction, szz = principal(trial)
    st, perm = descending(major, minor, szz)  # (3, r) sorted
    sp, sq = m.sin_phi, m.sin_psi
    b = np.stack([1.0 + sq, np.zeros_like(sq), -(1.0 - sq)])  # (3, r)
    Db = 2.0 * m.lam * sq + 2.0 * m.mu * b
    gam = ((1.0 + sp) * st[0] - (1.0 - sp) * st[2] - 2.0 * m.c * m.cos_phi) / ((1.0 + sp) * Db[0] - (1.0 - sp) * Db[2])
    back = unsorted(st - gam * Db, perm)
    return from_principal(back[0], back[1], direction, back[2]), unsorted(gam * b, perm)


def _tangent(trial, stress, active, m: Material, scale):
    """The algorithmic tangent (r, 4, 4) of returns onto the candidate sets ``active`` (r,) (indices
    into :data:`CANDIDATES`, in sorted principal axes; ``order`` of the trial's)."""
    major, minor, _, szz = principal(trial)
    order = order_of(descending(major, minor, szz)[1])  # as _return sorted them
    r = trial.shape[1]
    J = np.empty((r, 3, 3))
    a_all, b_all = np.empty((r, 6, 3)), np.empty((r, 6, 3))
    for j, (i1, i2) in enumerate(((0, 2), (1, 2), (0, 1))):
        a_all[:, j], b_all[:, j] = 0.0, 0.0
        a_all[:, j, i1], a_all[:, j, i2] = 1.0 + m.sin_phi, -(1.0 - m.sin_phi)
        b_all[:, j, i1], b_all[:, j, i2] = 1.0 + m.sin_psi, -(1.0 - m.sin_psi)
    a_all[:, 3:] = b_all[:, 3:] = np.eye(3)
    for k in np.unique(active):
        at = np.flatnonzero(active == k)
        cs = list(CANDIDATES[k])
        J[at] = active_set_jacobian(a_all[at][:, cs], b_all[at][:, cs], m.lam[at], m.mu[at])
    return full_tangent(trial, stress, unsort(J, order), m.lam, m.mu, scale)


def _return(trial, lam, mu, c, sp, cp, sq, t, scale):
    """The multi-surface return of trial states (4, m) that lie outside: stress (4, m) and
    principal plastic strain increments (3, m) in the trial's axes."""
    m = trial.shape[1]
    major, minor, direction, szz = principal(trial)
    st, perm = descending(major, minor, szz)
    st = st.T  # (m, 3) sorted σ1 ≥ σ2 ≥ σ3
    res = np.empty((m, 3))
    gam_strain = np.zeros((m, 3))
    active = np.zeros(m, np.int64)  # the candidate set each point returned onto
    # isotropic elasticity in principal axes: D = λ 1 1ᵀ + 2μ I. The main plane alone (most
    # returns) in closed form: a = (1 + sin φ, 0, -(1 - sin φ)), b likewise with ψ, D b, Δγ
    b_main = np.stack([1.0 + sq, np.zeros(m), -(1.0 - sq)], axis=1)  # (m, 3)
    Db = (2.0 * lam * sq)[:, None] + 2.0 * mu[:, None] * b_main
    with np.errstate(all="ignore"):
        gam = (((1.0 + sp) * st[:, 0] - (1.0 - sp) * st[:, 2] - 2.0 * c * cp)
               / ((1.0 + sp) * Db[:, 0] - (1.0 - sp) * Db[:, 2]))
        sig = st - gam[:, None] * Db
    ok = _admissible(gam[:, None], sig, c, sp, cp, t, scale)
    res[ok] = sig[ok]
    gam_strain[ok] = gam[ok, None] * b_main[ok]
    pending = ~ok
    rest = np.flatnonzero(pending)
    if rest.size:
        # the other candidate sets, at the points left: surfaces a, b (r, 6, 3)
        r = rest.size
        lam, mu, c, sp, cp, sq, t, scale, sr = (v[rest] for v in (lam, mu, c, sp, cp, sq, t, scale, st))
        A = np.zeros((r, 6, 3))
        B = np.zeros((r, 6, 3))
        for j, (i1, i2) in enumerate(((0, 2), (1, 2), (0, 1))):
            A[:, j, i1], A[:, j, i2] = 1.0 + sp, -(1.0 - sp)
            B[:, j, i1], B[:, j, i2] = 1.0 + sq, -(1.0 - sq)
        for j in range(3):
            A[:, 3 + j, j] = B[:, 3 + j, j] = 1.0
        k_const = np.zeros((r, 6))
        k_const[:, :3] = (2.0 * c * cp)[:, None]
        k_const[:, 3:] = t[:, None]
        left = np.ones(r, bool)
        for number, cand in enumerate(CANDIDATES[1:], start=1):
            p = np.flatnonzero(left)
            if p.size == 0:
                break
            cs = list(cand)
            a, b = A[p][:, cs], B[p][:, cs]  # (P, k, 3)
            Db = lam[p, None, None] * b.sum(axis=2, keepdims=True) + 2.0 * mu[p, None, None] * b  # (P, k, 3)
            M = np.einsum("pjx,plx->pjl", a, Db)
            rhs = np.einsum("pjx,px->pj", a, sr[p]) - k_const[p][:, cs]
            with np.errstate(all="ignore"):
                try:
                    gam = np.linalg.solve(M, rhs[..., None])[..., 0]
                except np.linalg.LinAlgError:
                    continue
            sig = sr[p] - np.einsum("pl,plx->px", gam, Db)
            ok = _admissible(gam, sig, c[p], sp[p], cp[p], t[p], scale[p])
            hit = p[ok]
            res[rest[hit]] = sig[ok]
            active[rest[hit]] = number
            gam_strain[rest[hit]] = np.einsum("pl,plx->px", gam[ok], b[ok])
            left[hit] = False
        pending[rest] = left
    if pending.any():
        raise ArithmeticError(f"Mohr-Coulomb return mapping found no admissible stress at {pending.sum()} points")
    # back to the trial's axes: undo the sort, then the in-plane directions
    back = unsorted(res.T, perm)
    return from_principal(back[0], back[1], direction, back[2]), unsorted(gam_strain.T, perm), active


def _admissible(gam, sig, c, sp, cp, t, scale) -> np.ndarray:
    """Koiter's conditions of candidate returns: multipliers ``gam`` (P, k) non-negative, stresses
    ``sig`` (P, 3) on or inside every surface, in the principal order, finite."""
    fv = yield_values(sig.T, c, sp, cp, t)
    return (np.all(gam >= -YIELD_TOL, axis=1) & np.all(fv <= YIELD_TOL * scale * 10, axis=0)
            & (sig[:, 0] >= sig[:, 1] - YIELD_TOL * scale) & (sig[:, 1] >= sig[:, 2] - YIELD_TOL * scale)
            & np.all(np.isfinite(sig), axis=1))


def equivalent(plastic_strain: np.ndarray) -> np.ndarray:
    """Equivalent plastic strain increment sqrt(2/3 Δεp : Δεp) of principal increments (3, n)."""
    return np.sqrt(2.0 / 3.0 * np.sum(plastic_strain**2, axis=0))
