"""Frictionless unilateral contact by the bolt-point method (Janovský & Procházka 1980, §3).

Notation (m interface nodes, SI units):

- ``B u`` is the normal jump ``[u]ν = u'·ν - u''·ν`` at the interface nodes (m);
  ``W = diag(weight)`` the trapezoid weights of the paper's quadrature I (m);
  ``lam`` the contact pressure λ (Pa); the nodal contact forces are ``B^T W lam``.
- Equilibrium ``K u + B^T W lam = f``. The ground stiffness ``K'`` is regular; the
  lining's ``K''`` has one zero mode ``r`` (vertical translation), so the lining
  displacement is ``u'' = K''^+ (f'' - B''^T W lam) + a r`` with ``K''^+`` the
  generalized inverse obtained by fixing one lining DOF away from the interface,
  and ``a`` (m) the lining's rigid vertical translation.
- The interface flexibility ``S = B K^+ B^T`` (m^2/N, dense m x m) and
  ``d = B K^+ f`` (m) give the gap for any pressure:
  ``gap(lam, a) = g0 - d + S W lam + a nu2``; the lining balance (paper Def. 2.6) is
  ``F2 + sum(nu2 w lam) = 0`` with ``F2`` the lining's vertical load (N/m).

The auxiliary problem (3.1) with a bolt at node A is: ``gap_A = 0`` (this fixes
``a``; it is step 1 of the paper's p,A-algorithm, "find u in V_A"), ``lam_A`` free
and given by the balance (3.12), and ``lam >= 0, gap >= 0, lam gap = 0`` at every
other node. Theorem 3.3: if ``lam_A >= 0`` it solves the contact problem (2.1).
Both inner solvers below solve the same auxiliary problem.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as la
from scipy.optimize import nnls
from scipy.sparse.linalg import eigsh

from ..errors import NoAdmissibleBoltError, NotConvergedError
from ..limits import check_time


log = logging.getLogger(__name__)


def pressure_scale(F2: float, nu2: np.ndarray, w: np.ndarray) -> float:
    """Mean pressure (Pa) that carries the lining's vertical load ``F2`` (N/m) over the lower
    half of the interface (normals ``nu2``, weights ``w``): the scale of every KKT check."""
    return abs(F2) / max(np.sum(np.abs(nu2) * w) / 2.0, 1e-300)


@dataclass(frozen=True)
class DualProblem:
    """The interface form of the contact problem (see the module docstring).

    S : (m, m) m^2/N; d, g0 : (m,) m; w : (m,) m; nu2 : (m,) vertical normal
    component; F2 : lining vertical load, N/m (negative: the weight).
    """

    S: np.ndarray
    d: np.ndarray
    g0: np.ndarray
    w: np.ndarray
    nu2: np.ndarray
    F2: float

    @property
    def m(self) -> int:
        return self.d.size

    def gap(self, lam: np.ndarray, bolt: int) -> tuple[np.ndarray, float]:
        """Gap g0 - [u]ν (m) and lining translation a (m) for ``lam`` with the bolt closed."""
        v = self.g0 - self.d + self.S @ (self.w * lam)
        a = -v[bolt] / self.nu2[bolt]
        gap = v + a * self.nu2
        gap[bolt] = 0.0
        return gap, a

    def bolt_pressure(self, lam: np.ndarray, bolt: int) -> float:
        """λ_A from the balance (3.12) given the other nodes' pressures."""
        rest = self.nu2 * self.w * lam
        return (-self.F2 - (rest.sum() - rest[bolt])) / (self.nu2[bolt] * self.w[bolt])

    @property
    def pressure_scale(self) -> float:
        return pressure_scale(self.F2, self.nu2, self.w)

    def reduced(self, bolt: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Reduced Hessian H and linear term b after eliminating λ_A by the balance.

        With x the pressures at the other nodes ``free`` (λ_A then follows from
        :meth:`bolt_pressure`), the dual objective is ``1/2 x^T H x - b^T x + const``
        and its gradient is ``W_F gap_F``. λ = λ0 + E x with E the identity on ``free``
        plus the row ``c = -(ν2 w)_F / (ν2 w)_A`` at A, so H = E^T WSW E costs O(m²).
        """
        w, nu2 = self.w, self.nu2
        free = np.flatnonzero(np.arange(self.m) != bolt)
        c = -(nu2[free] * w[free]) / (nu2[bolt] * w[bolt])
        WSW = (w[:, None] * self.S) * w[None, :]
        col = WSW[free, bolt]
        H = WSW[np.ix_(free, free)] + np.outer(col, c) + np.outer(c, col) + WSW[bolt, bolt] * np.outer(c, c)
        lam0_A = -self.F2 / (nu2[bolt] * w[bolt])
        v = w * (self.d - self.g0) - WSW[:, bolt] * lam0_A
        return free, 0.5 * (H + H.T), v[free] + c * v[bolt]


@dataclass
class InnerResult:
    lam: np.ndarray
    iterations: int
    converged: bool


@dataclass
class BoltTrial:
    node: int
    theta: float
    bolt_pressure: float
    iterations: int
    accepted: bool


@dataclass(kw_only=True)
class BoltedSolution:
    """What every interface model reports: the lining's rigid translation a (m) and the
    bolt search record (``bolt`` None, no trials, when no bolt is needed: ``bonded``)."""

    a: float
    bolt: int | None
    trials: list[BoltTrial] = field(default_factory=list)
    iterations: int = 0
    admissible: bool = True


@dataclass(kw_only=True)
class ContactSolution(BoltedSolution):
    """Frictionless contact: pressure λ (Pa) and gap (m), with the bolt search record."""

    lam: np.ndarray
    gap: np.ndarray


def _curvature(dual: DualProblem, bolt: int) -> float:
    """Largest eigenvalue L (m/Pa) of W_F^-1/2 H W_F^-1/2 by Lanczos (ARPACK).

    This is the Lipschitz constant of the reduced dual gradient in the W_F metric,
    so the Uzawa step ρ < 2/L converges (paper (3.15): ρ in (0, 2 C1/C2)).
    """
    free, H, _ = dual.reduced(bolt)
    s = 1.0 / np.sqrt(dual.w[free])
    M = (s[:, None] * H) * s[None, :]
    if M.shape[0] <= 64:
        L = float(la.eigvalsh(M)[-1])
    else:
        L = float(eigsh(M, k=1, which="LA", tol=1e-10, return_eigenvectors=False)[0])
    return L


def dual_kkt(dual: DualProblem, lam: np.ndarray, gap: np.ndarray, bolt: int) -> float:
    """The KKT measure of :func:`solver.contact.kkt.kkt_residual` on the interface (dimensionless).

    ``max(-gap / u_ref, |λ gap| / (p_ref u_ref), -λ / p_ref)`` over the non-bolt nodes, with
    ``p_ref = max(pressure_scale, max λ)`` and ``u_ref`` the size of the two terms whose
    difference is the jump, ``d`` and ``S W λ`` (or the clearance): a displacement scale
    comparable to the result's (its largest displacement); inner solvers stop below tol / 2.
    """
    p_ref = max(dual.pressure_scale, float(np.max(np.abs(lam))))
    u_ref = max(float(np.max(np.abs(dual.d))), float(np.max(np.abs(dual.S @ (dual.w * lam)))),
                float(np.max(dual.g0)), 1e-300)
    rest = np.arange(dual.m) != bolt
    g, lm = gap[rest], lam[rest]
    return max(max(0.0, -float(g.min(initial=0.0))) / u_ref,
               float(np.max(np.abs(lm * g), initial=0.0)) / (p_ref * u_ref),
               max(0.0, -float(lm.min(initial=0.0))) / p_ref)


#: Iterations with an unchanged contact set after which Uzawa tries the exact pressures of that set.
POLISH_AFTER = 50


def uzawa(dual: DualProblem, bolt: int, lam_init: np.ndarray, *, tol: float, max_iter: int) -> InnerResult:
    """The paper's p,A-algorithm (3.10)-(3.12) with ρ = 1.9 / L (see :func:`_curvature`).

    Stops only when :func:`dual_kkt` is below ``tol / 2`` (so the stored ``kkt_residual`` meets
    the tolerance), else reports non-convergence after ``max_iter`` iterations. L comes from
    Lanczos to 1e-10; ρ uses L enlarged by 1e-6 so that a slightly low estimate stays safe.

    The iteration identifies the contact set long before its pressures converge (its rate
    is set by the condition number of S). So whenever the set {λ > 0} has stayed the same
    for ``POLISH_AFTER`` iterations, the pressures of that set are computed exactly (one
    dense solve, as an active-set step does) and accepted only if they pass the same KKT
    test; otherwise the iteration simply continues from where it was.
    """
    L = _curvature(dual, bolt) * (1.0 + 1e-6)
    rho = 1.9 / L
    lam = np.maximum(lam_init, 0.0)
    lam[bolt] = dual.bolt_pressure(lam, bolt)
    not_bolt = np.arange(dual.m) != bolt
    gap, _ = dual.gap(lam, bolt)
    contact_set, same_for = lam > 0, 0
    for k in range(1, max_iter + 1):
        if k % 256 == 0:
            check_time("Uzawa contact iteration", k)
        lam = np.where(not_bolt, np.maximum(lam - rho * gap, 0.0), 0.0)  # (3.11), u in V_A (step 1) gave gap
        lam[bolt] = dual.bolt_pressure(lam, bolt)                        # (3.12)
        gap, _ = dual.gap(lam, bolt)
        if dual_kkt(dual, lam, gap, bolt) <= 0.5 * tol:
            return InnerResult(lam, k, True)
        now = lam > 0
        now[bolt] = True
        same_for = same_for + 1 if np.array_equal(now, contact_set) else 0
        contact_set = now
        if same_for == POLISH_AFTER:
            exact = solve_on_set(dual, now)
            exact_gap, _ = dual.gap(exact, bolt)
            if dual_kkt(dual, exact, exact_gap, bolt) <= 0.5 * tol:
                return InnerResult(exact, k, True)
    return InnerResult(lam, max_iter, False)


def active_set(dual: DualProblem, bolt: int, lam_init: np.ndarray, *, tol: float, max_iter: int) -> InnerResult:
    """Primal-dual active set (semismooth Newton) on the bolted dual; exact.

    Each step solves the equality-constrained system of the current active set
    A (gap = 0 on A, λ = 0 off A, balance) and updates
    A = {bolt} ∪ {i : λ_i - c gap_i > 0}, c = 1/L. It stops when A repeats (then
    λ >= 0 on A and gap >= 0 off A hold exactly). If an active set recurs (a
    cycle) or ``max_iter`` passes, the bolted dual QP is finished by the
    Lawson-Hanson NNLS active-set method, which terminates finitely.
    """
    m, w, S = dual.m, dual.w, dual.S
    L = float(np.max(np.diag(S) * w))  # scale only: c = 1/L makes λ and gap/L commensurate
    c = 1.0 / L
    lam = np.asarray(lam_init, float).copy()
    active = lam > 0 if np.any(lam[np.arange(m) != bolt] > 0) else np.ones(m, bool)
    active[bolt] = True
    seen = set()
    WSW = (w[:, None] * S) * w[None, :]
    rhs_full = w * (dual.d - dual.g0)
    for k in range(1, max_iter + 1):
        check_time("active-set contact iteration", k)
        key = np.packbits(active).tobytes()
        if key in seen:
            log.info("active set cycled after %d steps; finishing with NNLS", k)
            return _nnls(dual, bolt, k)
        seen.add(key)
        lam = solve_on_set(dual, active, WSW, rhs_full)
        gap, _ = dual.gap(lam, bolt)
        new = (lam - c * gap) > 0
        new[bolt] = True
        if np.array_equal(new, active):
            return InnerResult(lam, k, True)
        active = new
    return _nnls(dual, bolt, max_iter)


def solve_on_set(dual: DualProblem, active: np.ndarray, WSW: np.ndarray | None = None,
                 rhs_full: np.ndarray | None = None) -> np.ndarray:
    """λ with gap = 0 on ``active`` (bolt included), λ = 0 elsewhere, and the balance."""
    w = dual.w
    if WSW is None:
        WSW = (w[:, None] * dual.S) * w[None, :]
    if rhs_full is None:
        rhs_full = w * (dual.d - dual.g0)
    idx = np.flatnonzero(active)
    n = idx.size
    A, c, r = WSW[np.ix_(idx, idx)], (w * dual.nu2)[idx], rhs_full[idx]
    lam = np.zeros(dual.m)
    try:
        # [[A, c], [cᵀ, 0]] [λ; μ] = [r; -F2] with A SPD (a flexibility block): by A's
        # Cholesky factor, half the work of a symmetric indefinite solve of the whole
        X = la.cho_solve(la.cho_factor(A, check_finite=False), np.column_stack([r, c]), check_finite=False)
        mu = (c @ X[:, 0] + dual.F2) / (c @ X[:, 1])
        lam[idx] = X[:, 0] - mu * X[:, 1]
    except la.LinAlgError:  # A singular to working precision: the bordered system as a whole
        B = np.zeros((n + 1, n + 1))
        B[:n, :n], B[:n, n], B[n, :n] = A, c, c
        lam[idx] = la.solve(B, np.r_[r, -dual.F2], assume_a="sym")[:n]
    return lam


def _nnls(dual: DualProblem, bolt: int, iterations: int) -> InnerResult:
    free, H, b = dual.reduced(bolt)
    R = la.cholesky(H)  # H = R^T R
    z = la.solve_triangular(R, b, trans="T")
    x, _ = nnls(R, z, maxiter=50 * H.shape[0])
    lam = np.zeros(dual.m)
    lam[free] = x
    lam[bolt] = dual.bolt_pressure(lam, bolt)
    return InnerResult(lam, iterations + 1, True)


INNER = {"uzawa": uzawa, "active-set": active_set}


def search_bolt(theta: np.ndarray, nu2: np.ndarray, solve_at, *, tol: float, p_ref: float,
                bolt: float | str = "auto", model: str = "frictionless", upward: bool = False):
    """The paper's global strategy: guess a bolt A, solve (3.1), accept when λ_A >= 0.

    Candidates are the nodes with ν2 != 0 (the set N0). The first guess is the
    invert (the floating lining rests on it under its own weight), or the crown when the
    lining's vertical load is ``upward`` (a watertight lining lighter than the water it
    displaces is pushed up against the crown; the paper's method allows either sign); after a
    rejected guess the next is the untried node with the largest pressure in the
    rejected auxiliary solution (where the bolted lining presses hardest), ties
    broken towards the invert. Every trial is recorded.

    ``solve_at(A)`` solves the auxiliary problem with the bolt at node A and returns
    ``(lam, iterations, result)``: the (m,) pressures, the inner iterations and whatever
    the caller needs back. Returns ``(A, result, trials, iterations, admissible)``.

    With ``bolt`` a theta in degrees, the nearest node of N0 is the only bolt;
    a negative bolt reaction is then reported (``admissible=False``), not hidden.
    """
    candidates = np.flatnonzero(np.abs(nu2) > 1e-12)
    if bolt != "auto":
        order = [int(candidates[np.argmin(np.abs(theta[candidates] - float(bolt)))])]
    else:
        pick = np.argmin if upward else np.argmax
        order = [int(candidates[pick(theta[candidates])])]
    tried: set[int] = set()
    trials: list[BoltTrial] = []
    total = 0
    while order:
        A = order.pop(0)
        tried.add(A)
        lam, iterations, result = solve_at(A)
        total += iterations
        lam_A = float(lam[A])
        ok = lam_A >= -tol * max(p_ref, float(np.max(np.abs(lam))))
        trials.append(BoltTrial(A, float(theta[A]), lam_A, iterations, bool(ok)))
        log.debug("%s bolt trial at theta=%.2f: lambda_A=%.4g Pa (%s)", model, theta[A], lam_A, ok)
        if ok or bolt != "auto":
            return A, result, trials, total, bool(ok)
        rest = np.array([i for i in candidates if i not in tried], dtype=np.int64)
        if rest.size:
            score = np.lexsort((theta[rest], lam[rest]))  # largest λ, then nearest the invert
            order = [int(rest[score[-1]])]
    raise NoAdmissibleBoltError(
        f"interface.model={model!r}: no admissible bolt among {len(tried)} candidates (every bolt "
        "reaction was negative); check the loads and solver.tolerance")


def solve_contact(dual: DualProblem, theta: np.ndarray, *, inner: str, tol: float,
                  max_iterations: int, bolt: float | str = "auto") -> ContactSolution:
    """Frictionless contact: :func:`search_bolt` around the inner solver ``inner``, each
    trial starting from the previous trial's pressures."""
    solver = INNER[inner]
    lam = np.zeros(dual.m)

    def solve_at(A: int):
        nonlocal lam
        res = solver(dual, A, lam, tol=tol, max_iter=max_iterations)
        if not res.converged:
            raise NotConvergedError(
                f"solver.inner={inner!r} did not converge in {max_iterations} iterations "
                f"(bolt at theta={theta[A]:.2f} deg); raise solver.max_iterations or use 'active-set'")
        lam = res.lam
        return lam, res.iterations, lam

    A, lam, trials, total, ok = search_bolt(theta, dual.nu2, solve_at, tol=tol, p_ref=dual.pressure_scale,
                                            bolt=bolt, upward=dual.F2 > 0)
    gap, a = dual.gap(lam, A)
    return ContactSolution(lam=lam, gap=gap, a=a, bolt=A, trials=trials, iterations=total, admissible=ok)
