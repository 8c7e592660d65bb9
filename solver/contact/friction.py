"""Coulomb friction on the interface (SPEC §1.2): bolt search outside, active sets inside.

Notation (:mod:`solver.fe.flexibility`): R = m + (m - 2) interface rows, ``t = [λ; s]`` (Pa)
the tractions on the lining, ``W = diag(w)`` (m) the quadrature, the jumps
``J = d - S W t - a r`` (m) with ``a`` the lining's rigid upward translation; the gap is
``g0 - J[:m]`` and ``[u]τ = J[m:]``. Tangential row ``m + k`` belongs to node ``k + 1``
(crown and invert carry no shear, by symmetry). The conditions are

- λ ≥ 0, gap ≥ 0, λ·gap = 0 (unilateral contact);
- |s| ≤ μλ; [u]τ = 0 where |s| < μλ; [u]τ = β s/|s|, β ≥ 0, where |s| = μλ (the shear on
  the lining points along the ground's slip relative to the lining: the lining slips
  against s);
- the lining's vertical balance ``F2 + rᵀ W t = 0``.

Outer loop: the paper's bolt search (§3, as :func:`solver.contact.bolt.solve_contact`).
With a bolt at A, ``gap_A = 0`` fixes ``a`` and λ_A is free (no sign condition); the
trial is accepted when λ_A ≥ 0.

Inner solver: a primal-dual active set method (semismooth Newton on the natural maps of
Hüeber, Stadler & Wohlmuth, SIAM J. Sci. Comput. 30 (2008), in its 2D set form). Each
node is *free* (λ = 0, s = 0), *stick* (gap = 0, [u]τ = 0) or *slip* (gap = 0,
s = μλσ with σ = ±1); one step solves the linear system of the current sets with the
balance row (unknowns: λ on the contact set, s on the stick set, ``a``) and updates the
sets from ``λ - c gap`` and ``s + c [u]τ`` (c = 1/max(diag(S) w) makes pressures and
jumps commensurate, as in :func:`solver.contact.bolt.active_set`). When the sets and slip
signs repeat, every condition holds exactly: stick nodes have |s| ≤ μλ, slip nodes have
``σ [u]τ > 0`` and λ > 0, free nodes have gap ≥ 0. Why this method: it terminates in
finitely many steps with the exact solution of the discrete problem (the answer does not
depend on a penalty parameter or on an iteration's tolerance), each step is one dense
solve of at most R + 1 unknowns on the interface already condensed by
:class:`~solver.model.TunnelModel`, and it typically needs a handful of steps.

Cycle guard: Coulomb friction makes the problem non-monotone, so the set iteration
may cycle. Then a fixed point on the slip bound takes over: with g = μ max(λ, 0) frozen
the problem is Tresca friction, a convex quadratic programme in the tractions (the
dual: λ_A eliminated by the balance, bounds λ ≥ 0 and -g ≤ s ≤ g) which is solved
exactly and finitely by the bounded-variable least-squares active-set method (BVLS,
Stark & Parker) on its Cholesky factor; after each Tresca solve the set iteration is
restarted from its sets and usually ends at once. The fixed point converges for the
small-to-moderate μ for which the discrete Coulomb problem is known to be unique.
Both paths stop only when the KKT measure of :func:`coulomb_kkt` (that of
:func:`solver.contact.kkt.kkt_residual` on the interface, friction natural map included) is
below ``tol / 2``.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import scipy.linalg as la
from scipy.optimize import lsq_linear

from .bolt import BoltedSolution, NotConvergedError, pressure_scale, search_bolt
from ..limits import check_time

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class FrictionProblem:
    """The interface form of the Coulomb contact stage (see the module docstring).

    S : (R, R) m/Pa per m of interface, the flexibility; d, w, r : (R,) jumps of the
    loads (m), quadrature weights (m), jumps of a unit upward lining translation (1);
    g0 : clearance (m); F2 : lining vertical load (N/m, negative); m : interface nodes;
    mu : friction coefficient.
    """

    S: np.ndarray
    d: np.ndarray
    g0: float
    w: np.ndarray
    r: np.ndarray
    F2: float
    m: int
    mu: float

    @property
    def pressure_scale(self) -> float:
        return pressure_scale(self.F2, self.r[:self.m], self.w[:self.m])

    def jumps(self, t: np.ndarray, bolt: int) -> tuple[np.ndarray, float]:
        """Jumps J (R,) m and the translation a (m) that closes the bolt (gap_A = 0)."""
        v = self.d - self.S @ (self.w * t)
        a = (v[bolt] - self.g0) / self.r[bolt]
        return v - a * self.r, float(a)


@dataclass(kw_only=True)
class CoulombSolution(BoltedSolution):
    """Tractions t = [λ; s] (Pa), with the lining translation and the bolt search record."""

    t: np.ndarray


@dataclass
class _Sets:
    """Per node: in contact (m,); per tangential row: stick, slip and the slip sign (m-2,)."""

    contact: np.ndarray
    stick: np.ndarray
    slip: np.ndarray
    sign: np.ndarray

    def key(self) -> bytes:
        return np.packbits(np.r_[self.contact, self.stick, self.slip, self.sign > 0]).tobytes()


def coulomb_kkt(fp: FrictionProblem, t: np.ndarray, J: np.ndarray, bolt: int) -> float:
    """KKT measure of :func:`solver.contact.kkt.kkt_residual` on the interface (dimensionless).

    Normal part as :func:`solver.contact.bolt.dual_kkt` (the bolt's normal row excluded) and the
    friction natural map ``|s - proj_[-μλ, μλ](s + c [u]τ)| / p_ref``, c = p_ref / u_ref;
    ``p_ref = max(pressure_scale, max |t|)``, ``u_ref`` the size of d, S W t and g0.
    """
    m = fp.m
    p_ref = max(fp.pressure_scale, float(np.max(np.abs(t))))
    u_ref = max(float(np.max(np.abs(fp.d))), float(np.max(np.abs(fp.S @ (fp.w * t)))), fp.g0, 1e-300)
    lam, s = t[:m], t[m:]
    gap, jt = fp.g0 - J[:m], J[m:]
    rest = np.arange(m) != bolt
    g, lm = gap[rest], lam[rest]
    bound = fp.mu * np.maximum(lam[1:m - 1], 0.0)
    nat = s - np.clip(s + (p_ref / u_ref) * jt, -bound, bound)
    return max(max(0.0, -float(g.min(initial=0.0))) / u_ref,
               float(np.max(np.abs(lm * g), initial=0.0)) / (p_ref * u_ref),
               max(0.0, -float(lm.min(initial=0.0))) / p_ref,
               float(np.max(np.abs(nat), initial=0.0)) / p_ref)


def _solve_sets(fp: FrictionProblem, SW: np.ndarray, sets: _Sets, bolt: int) -> np.ndarray:
    """Tractions t (R,) of the given sets: gap = 0 on contact, J = 0 on stick, s = μλσ on slip."""
    m, R = fp.m, fp.d.size
    contact = sets.contact.copy()
    contact[bolt] = True
    lam_rows = np.flatnonzero(contact)
    stick_rows = m + np.flatnonzero(sets.stick)
    slip = np.flatnonzero(sets.slip)
    n1, n2 = lam_rows.size, stick_rows.size
    n = n1 + n2
    col_of_node = np.full(m, -1)
    col_of_node[lam_rows] = np.arange(n1)
    cols = np.r_[lam_rows, stick_rows]  # y = [λ on contact; s on stick]; slip s = μσλ of its node
    eq = cols
    rows = SW[eq]
    A = np.zeros((n + 1, n + 1))
    A[:n, :n] = rows[:, cols]
    if slip.size:
        slip_part = rows[:, m + slip] * (fp.mu * sets.sign[slip])
        np.add.at(A[:n, :n].T, col_of_node[slip + 1], slip_part.T)
    A[:n, n] = fp.r[eq]
    wr = fp.w * fp.r
    A[n, :n] = wr[cols]
    if slip.size:
        np.add.at(A[n], col_of_node[slip + 1], wr[m + slip] * fp.mu * sets.sign[slip])
    rhs = np.r_[fp.d[eq] - np.where(eq < m, fp.g0, 0.0), -fp.F2]
    y = np.linalg.solve(A, rhs)  # LU (gesv): scipy 1.17 linalg.solve (general) measured ~100x slower here
    t = np.zeros(R)
    t[cols] = y[:n]
    t[m + slip] = fp.mu * sets.sign[slip] * t[slip + 1]
    return t


def _update(fp: FrictionProblem, t: np.ndarray, J: np.ndarray, c: float, bolt: int) -> _Sets:
    """New sets from the natural maps: contact where λ - c gap > 0, slip where |s + c[u]τ| > μ(λ - c gap)."""
    m = fp.m
    z_n = t[:m] - c * (fp.g0 - J[:m])
    contact = z_n > 0
    contact[bolt] = True
    bound = fp.mu * np.maximum(z_n[1:m - 1], 0.0)
    z_t = t[m:] + c * J[m:]
    held = contact[1:m - 1] & (bound > 0)
    stick = held & (np.abs(z_t) <= bound)
    slip = held & ~stick
    return _Sets(contact, stick, slip, np.where(slip, np.sign(z_t), 0.0))


def _bonded_sets(m: int) -> _Sets:
    return _Sets(np.ones(m, bool), np.ones(m - 2, bool), np.zeros(m - 2, bool), np.zeros(m - 2))


def _active_set(fp, SW, c, bolt, sets, *, tol, max_iter):
    """Set iteration from ``sets``: (t, sets, steps, status), status 'done', 'cycle' or 'limit'."""
    seen: set[bytes] = set()
    t = np.zeros(fp.d.size)
    for k in range(1, max_iter + 1):
        check_time("Coulomb active-set iteration", k)
        seen.add(sets.key())
        try:
            t = _solve_sets(fp, SW, sets, bolt)
        except np.linalg.LinAlgError:
            return t, sets, k, "cycle"  # a singular set system: let the fixed point take over
        J, _ = fp.jumps(t, bolt)
        new = _update(fp, t, J, c, bolt)
        if new.key() == sets.key():
            if coulomb_kkt(fp, t, J, bolt) <= 0.5 * tol:
                return t, sets, k, "done"
            return t, sets, k, "cycle"  # exact sets but a poor solve: rounding, hand over
        if new.key() in seen:
            return t, new, k, "cycle"
        sets = new
    return t, sets, max_iter, "limit"


def _tresca(fp: FrictionProblem, WSW: np.ndarray, bolt: int, t: np.ndarray) -> np.ndarray:
    """Exact Tresca step from ``t``: with the slip bound g = μ max(λ, 0) of ``t`` frozen, minimize
    ½ t'ᵀWSWt' - t'ᵀW(d - g0 on normal rows) with the balance, λ' ≥ 0 off the bolt, |s'| ≤ g;
    λ'_A is eliminated by the balance, and ``t`` is the starting point of :func:`_box_qp`."""
    m, R = fp.m, fp.d.size
    g = fp.mu * np.maximum(t[1:m - 1], 0.0)
    wr = fp.w * fp.r
    held = np.r_[np.ones(m, bool), g > 0]
    held[bolt] = False
    free = np.flatnonzero(held)
    c = -wr[free] / wr[bolt]  # t = t0 + E x: E is the identity on ``free`` plus the row c at the bolt
    t0 = np.zeros(R)
    t0[bolt] = -fp.F2 / wr[bolt]
    v = fp.w * (fp.d - np.r_[np.full(m, fp.g0), np.zeros(R - m)]) - WSW[:, bolt] * t0[bolt]
    col = WSW[free, bolt]
    H = WSW[np.ix_(free, free)] + np.outer(col, c) + np.outer(c, col) + WSW[bolt, bolt] * np.outer(c, c)
    b = v[free] + c * v[bolt]
    upper = np.r_[np.full(m, np.inf), g][free]
    lower = np.where(free < m, 0.0, -upper)
    x = _box_qp(0.5 * (H + H.T), b, lower, upper, t[free])
    out = t0.copy()
    out[free] = x
    out[bolt] += c @ x
    return out


def _box_qp(H: np.ndarray, b: np.ndarray, lower: np.ndarray, upper: np.ndarray, x0: np.ndarray) -> np.ndarray:
    """Minimize ½ xᵀHx - bᵀx on lower ≤ x ≤ upper (H SPD), exactly, starting from ``x0``.

    Primal-dual active sets (Hintermüller, Ito & Kunisch 2002) in the unit-diagonal scaling;
    if a set recurs, bounded-variable least squares (BVLS, finite) on the Cholesky factor.
    """
    scale = np.sqrt(np.diag(H))
    Hs, bs, lo, hi = H / np.outer(scale, scale), b / scale, lower * scale, upper * scale
    x = np.clip(x0 * scale, lo, hi)
    seen: set[bytes] = set()
    at_lo = at_hi = np.zeros(bs.size, bool)
    for _ in range(4 * bs.size + 10):
        y = x - (Hs @ x - bs)  # c = 1 on the unit diagonal
        new_lo, new_hi = y < lo, y > hi
        key = np.packbits(np.r_[new_lo, new_hi]).tobytes()
        if np.array_equal(new_lo, at_lo) and np.array_equal(new_hi, at_hi) and seen:
            return x / scale
        if key in seen:
            break
        seen.add(key)
        at_lo, at_hi = new_lo, new_hi
        x = np.where(at_lo, lo, np.where(at_hi, hi, 0.0))
        inner = ~(at_lo | at_hi)
        if inner.any():
            rhs = bs[inner] - Hs[np.ix_(inner, ~inner)] @ x[~inner]
            x[inner] = la.solve(Hs[np.ix_(inner, inner)], rhs, assume_a="pos", check_finite=False)
    log.info("Tresca active sets cycled; finishing with BVLS")
    U = la.cholesky(Hs)  # Hs = Uᵀ U
    z = la.solve_triangular(U, bs, trans="T")
    return lsq_linear(U, z, bounds=(lo, hi), method="bvls", tol=1e-14, max_iter=20 * bs.size).x / scale


def solve_bolted(fp: FrictionProblem, bolt: int, sets: _Sets, *, tol: float, max_iter: int):
    """Coulomb contact with the bolt at node ``bolt``: (t, sets, iterations).

    The set iteration first; on a cycle, Tresca fixed-point steps g = μ max(λ, 0), each
    followed by the set iteration from the Tresca solution's sets.
    """
    SW = fp.S * fp.w[None, :]
    c = 1.0 / float(np.max(np.diag(fp.S) * fp.w))
    t, sets, steps, status = _active_set(fp, SW, c, bolt, sets, tol=tol, max_iter=max_iter)
    if status == "done":
        return t, sets, steps
    log.info("Coulomb active sets %s after %d steps (bolt node %d); Tresca fixed point",
             status, steps, bolt)
    WSW = fp.w[:, None] * SW
    while steps < max_iter:
        if steps % 64 == 0:
            check_time("Coulomb fixed-point iteration", steps)
        t = _tresca(fp, WSW, bolt, t)
        steps += 1
        J, _ = fp.jumps(t, bolt)
        if coulomb_kkt(fp, t, J, bolt) <= 0.5 * tol:
            return t, _update(fp, t, J, c, bolt), steps
        t_as, sets_as, k, status = _active_set(fp, SW, c, bolt, _update(fp, t, J, c, bolt), tol=tol,
                                               max_iter=min(10, max_iter - steps))
        steps += k
        if status == "done":
            return t_as, sets_as, steps
    raise NotConvergedError(
        f"interface.model='coulomb' (mu={fp.mu:g}): the active sets and the Tresca fixed point did not "
        f"reach solver.tolerance={tol:g} in solver.max_iterations={max_iter} steps (bolt node {bolt}); "
        "raise solver.max_iterations or lower interface.friction")


def solve_coulomb(fp: FrictionProblem, theta: np.ndarray, *, tol: float, max_iterations: int,
                  bolt: float | str = "auto") -> CoulombSolution:
    """:func:`solver.contact.bolt.search_bolt` around :func:`solve_bolted`; each trial starts from
    the previous trial's sets (the first from all nodes stuck)."""
    m = fp.m
    sets = _bonded_sets(m)

    def solve_at(A: int):
        nonlocal sets
        t, sets, its = solve_bolted(fp, A, sets, tol=tol, max_iter=max_iterations)
        return t[:m], its, t

    A, t, trials, total, ok = search_bolt(theta, fp.r[:m], solve_at, tol=tol, p_ref=fp.pressure_scale,
                                          bolt=bolt, model="coulomb", upward=fp.F2 > 0)
    _, a = fp.jumps(t, A)
    return CoulombSolution(t=t, a=a, bolt=A, trials=trials, iterations=total, admissible=ok)
