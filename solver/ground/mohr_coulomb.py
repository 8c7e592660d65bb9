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
from numba import njit

from .principal import descending, extremes, from_principal, order_of, principal, put_back, sorted_at, unsorted
from .tangent import active_set_jacobian, full_tangent, unsort

#: Relative tolerance of "on or inside a surface" (to the stresses' scale).
YIELD_TOL = 1e-9


def yield_values(s: np.ndarray, cohesion, sin_phi, cos_phi, tensile) -> np.ndarray:
    """(4, n) values of the main Mohr–Coulomb plane and the three tension cut-offs at sorted
    principal stresses ``s`` (3, n); ≤ 0 inside."""
    main = (s[0] - s[2]) + (s[0] + s[2]) * sin_phi - 2.0 * cohesion * cos_phi
    return np.vstack([main, s - tensile])


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
        # (writable copies: the compiled return is specialized on its arrays' flags, one kind)
        bc = lambda v: np.array(np.broadcast_to(np.asarray(v, dtype=float), (n,)))  # noqa: E731
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
    multiplier). The return is then smooth in the trial (the tangent of a fixed active set, as a Newton step
    on it would take); ``at_yield`` flags the points outside."""
    return _stress(trial, mat, flag_tolerance, True, frozen)


def _stress(trial: np.ndarray, mat: Material, flag_tolerance: float, tangent: bool, frozen=None):
    n = trial.shape[1]
    stress, dep = np.empty((4, n)), np.empty((3, n))
    at_yield, active, scale = np.empty(n, bool), np.empty(n, np.int64), np.empty(n)
    may = np.ones(n, bool) if frozen is None else np.asarray(frozen, bool)
    failed = _returns(np.ascontiguousarray(trial, float), *mat, float(flag_tolerance), may, stress, dep, at_yield,
                      active, scale)
    if failed:
        raise ArithmeticError(f"Mohr-Coulomb return mapping found no admissible stress at {failed} points")
    if not tangent and frozen is None:
        return stress, dep, at_yield
    todo = np.flatnonzero(active >= 0)
    C = np.zeros((0, 4, 4))
    if tangent and todo.size:
        C = _tangent(trial[:, todo], stress[:, todo], active[todo], mat.at(todo), scale[todo])
    if frozen is not None:  # inside the surface, yet held flowing: onto the main plane all the same
        forced = np.flatnonzero(may & (active == INSIDE))
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


#: :func:`_returns`' ``active`` of a point inside the surface, and of one outside it that may not return
INSIDE, HELD = -1, -2
#: :data:`CANDIDATES` padded with -1 (c, 4), and their sizes (c,): what the compiled return reads
_CANDIDATE_SETS = np.array([c + (-1,) * (4 - len(c)) for c in CANDIDATES], np.int64)
_CANDIDATE_SIZES = np.array([len(c) for c in CANDIDATES], np.int64)


@njit(cache=True)
def _returns(trial, lam, mu, c, sin_phi, cos_phi, sin_psi, tensile, flag, may, stress, dep, at_yield, active,
             scale):
    """The return of every point of ``trial`` (4, n), compiled: one pass over the points, each screened on its
    largest and least principal stresses and, where outside (and ``may`` return), returned (:func:`_onto`);
    fills ``stress`` (4, n), the principal plastic strain increments ``dep`` (3, n) in the trial's axes,
    ``at_yield``, the candidate set returned onto ``active`` (:data:`INSIDE`, :data:`HELD`) and the stress
    scale ``max(|σ1|, |σ3|, c, 1 Pa)``. Returns how many points found no admissible return."""
    st, res, ep = np.empty(3), np.empty(3), np.empty(3)
    work = (np.empty((4, 3)), np.empty((4, 3)), np.empty((4, 3)), np.empty((4, 4)), np.empty(4), np.empty(3))
    failed = 0
    for i in range(trial.shape[1]):
        s1, s3 = extremes(trial, i)
        scale[i] = sc = max(max(s1, -s3), max(c[i], 1.0))
        f = max((s1 - s3) + (s1 + s3) * sin_phi[i] - 2.0 * c[i] * cos_phi[i], s1 - tensile[i])
        outside = f > YIELD_TOL * sc
        at_yield[i] = outside or f > -flag * sc
        for x in range(4):
            stress[x, i] = trial[x, i]
        dep[0, i] = dep[1, i] = dep[2, i] = 0.0
        active[i] = INSIDE if not outside else (HELD if not may[i] else INSIDE)
        if not outside or active[i] == HELD:
            continue
        top, middle, c2, s2 = sorted_at(trial, i, st)
        active[i] = _onto(st, lam[i], mu[i], c[i], sin_phi[i], cos_phi[i], sin_psi[i], tensile[i], sc, res, ep, work)
        if active[i] < 0:
            failed += 1
        else:
            put_back(i, top, middle, c2, s2, res, ep, stress, dep)
    return failed


@njit(cache=True)
def _onto(st, lam, mu, c, sp, cp, sq, t, scale, res, ep, work):
    """The multi-surface return of sorted principal trial stresses ``st`` (3,): the first candidate set (in
    :data:`CANDIDATES`' order; the main plane in closed form) whose multipliers solve its planes and pass
    Koiter's conditions (:func:`_admissible`) gives the stress ``res`` and plastic strain increments ``ep``
    (sorted axes); returns its index, -1 if none does."""
    A, B, Db, M, g, sig = work
    b0, b2 = 1.0 + sq, -(1.0 - sq)
    d0, d1, d2 = 2.0 * lam * sq + 2.0 * mu * b0, 2.0 * lam * sq, 2.0 * lam * sq + 2.0 * mu * b2
    den = (1.0 + sp) * d0 - (1.0 - sp) * d2
    g[0] = ((1.0 + sp) * st[0] - (1.0 - sp) * st[2] - 2.0 * c * cp) / den if den != 0.0 else np.nan
    res[0], res[1], res[2] = st[0] - g[0] * d0, st[1] - g[0] * d1, st[2] - g[0] * d2
    if _admissible(g, 1, res, c, sp, cp, t, scale):
        ep[0], ep[1], ep[2] = g[0] * b0, 0.0, g[0] * b2
        return 0
    for number in range(1, _CANDIDATE_SIZES.size):
        k = _CANDIDATE_SIZES[number]
        for j in range(k):
            surface = _CANDIDATE_SETS[number, j]
            _plane(surface, sp, A[j])
            _plane(surface, sq, B[j])
            trace = B[j, 0] + B[j, 1] + B[j, 2]
            for x in range(3):
                Db[j, x] = lam * trace + 2.0 * mu * B[j, x]
            g[j] = A[j, 0] * st[0] + A[j, 1] * st[1] + A[j, 2] * st[2] - (2.0 * c * cp if surface < 3 else t)
        for j in range(k):
            for m in range(k):
                M[j, m] = A[j, 0] * Db[m, 0] + A[j, 1] * Db[m, 1] + A[j, 2] * Db[m, 2]
        if not _solve(M, g, k):
            continue
        for x in range(3):
            sig[x] = st[x]
            for m in range(k):
                sig[x] -= g[m] * Db[m, x]
        if _admissible(g, k, sig, c, sp, cp, t, scale):
            for x in range(3):
                res[x], ep[x] = sig[x], 0.0
                for m in range(k):
                    ep[x] += g[m] * B[m, x]
            return number
    return -1


@njit(cache=True)
def _plane(surface, s, out):
    """The normal (``s`` = sin φ) or flow direction (sin ψ) of a surface (:data:`CANDIDATES`' numbering) into
    ``out`` (3,)."""
    out[0] = out[1] = out[2] = 0.0
    if surface < 3:
        i, j = ((0, 2), (1, 2), (0, 1))[surface]
        out[i], out[j] = 1.0 + s, -(1.0 - s)
    else:
        out[surface - 3] = 1.0


@njit(cache=True)
def _admissible(g, k, sig, c, sp, cp, t, scale) -> bool:
    """Koiter's conditions of a candidate return: multipliers ``g[:k]`` non-negative, the stress ``sig`` (3,)
    on or inside every surface, in the principal order, finite."""
    for m in range(k):
        if not g[m] >= -YIELD_TOL:
            return False
    s0, s1, s2, lim = sig[0], sig[1], sig[2], YIELD_TOL * scale * 10
    return ((s0 - s2) + (s0 + s2) * sp - 2.0 * c * cp <= lim and max(s0, max(s1, s2)) - t <= lim
            and s0 >= s1 - YIELD_TOL * scale and s1 >= s2 - YIELD_TOL * scale
            and np.isfinite(s0) and np.isfinite(s1) and np.isfinite(s2))


@njit(cache=True)
def _solve(M, g, k) -> bool:
    """Solve the k×k system ``M x = g`` in place (``g`` ← x) by Gaussian elimination with partial pivoting;
    False where it is singular."""
    for col in range(k):
        piv = col
        for r in range(col + 1, k):
            if abs(M[r, col]) > abs(M[piv, col]):
                piv = r
        if M[piv, col] == 0.0:
            return False
        if piv != col:
            for x in range(k):
                M[col, x], M[piv, x] = M[piv, x], M[col, x]
            g[col], g[piv] = g[piv], g[col]
        for r in range(col + 1, k):
            f = M[r, col] / M[col, col]
            for x in range(col, k):
                M[r, x] -= f * M[col, x]
            g[r] -= f * g[col]
    for col in range(k - 1, -1, -1):
        for x in range(col + 1, k):
            g[col] -= M[col, x] * g[x]
        g[col] /= M[col, col]
    return True


def equivalent(plastic_strain: np.ndarray) -> np.ndarray:
    """Equivalent plastic strain increment sqrt(2/3 Δεp : Δεp) of principal increments (3, n)."""
    return np.sqrt(2.0 / 3.0 * np.sum(plastic_strain**2, axis=0))
