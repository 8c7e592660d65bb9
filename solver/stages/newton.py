"""Newton's method with a line search on a preconditioned residual, its linear systems solved by
GMRES (SPEC §9.1).

The plastic equilibrium of an increment is ``F(x) = x - K⁻¹(f + p(x) - …) = 0`` (the elastic
stiffness ``K``, factorized once per model, as the preconditioner: ``F`` is the residual ``K x -
f - p(x)`` premultiplied by ``K⁻¹``). Its Jacobian ``I - K⁻¹ P′`` differs from the identity only
through the points that yield, so GMRES resolves a Newton step in a few Krylov steps, each one
triangular solve pair on the factor the model already holds (Knoll & Keyes 2004, Newton–Krylov;
the forcing terms are Eisenstat & Walker's 1996 second choice). The step is damped by a
backtracking line search on ``‖F‖`` (Armijo), which GMRES's step decreases whenever it solved its
system to better than ``‖F‖``.
"""
from __future__ import annotations

import logging
from typing import Callable

import numpy as np

from ..limits import check_time

log = logging.getLogger(__name__)

#: Newton iterations allowed per (sub-)increment.
NEWTON_ITERATIONS = 12
#: Krylov steps allowed per Newton step (one restart-free GMRES cycle).
KRYLOV_STEPS = 80
#: Newton's iteration has stalled when the force has not halved in this many steps: the increment
#: is then better split (:func:`solver.stages.plastic._follow`) than iterated on.
STALL_STEPS = 3
#: Forcing terms: the first Newton step's and the bounds of the later ones' (Eisenstat–Walker).
ETA_FIRST, ETA_MIN, ETA_MAX = 0.1, 1e-6, 0.1
#: Line search: sufficient decrease (Armijo) and the least step tried.
ARMIJO, LEAST_STEP = 1e-4, 1.0 / 64
#: Active-set steps (frozen sets of flowing points) allowed to finish an increment.
ACTIVE_SET_STEPS = 12
#: Residual norms the non-monotone line search compares with (:func:`_line_search`).
MEMORY = 4
#: The regularizations θ tried in turn where Newton's step fails (:func:`newton`).
REGULARIZATION = (0.0, 0.05, 0.3, 1.0)


class Stalled(Exception):
    """Newton's iteration of one (sub-)increment stopped short of equilibrium: its least
    out-of-balance force, the tolerance and the residual evaluations it took."""

    def __init__(self, force: float, atol: float, iterations: int, reason: str, best=None, krylov: int = 0):
        super().__init__(force, atol, iterations, reason)
        self.force, self.atol, self.iterations, self.reason = force, atol, iterations, reason
        #: the iterate of least force and its state, and the Krylov steps spent
        self.best, self.krylov = best, krylov


def gmres(apply: Callable[[np.ndarray], np.ndarray], b: np.ndarray, rtol: float, limit: int = KRYLOV_STEPS):
    """GMRES from zero for ``A x = b`` (``A`` as ``apply``), to ``‖b - A x‖ ≤ rtol ‖b‖`` or ``limit``
    steps (modified Gram–Schmidt, Givens rotations). Returns ``x``, the relative residual and the
    steps taken."""
    beta = float(np.linalg.norm(b))
    if beta == 0.0:
        return np.zeros_like(b), 0.0, 0
    V = np.empty((limit + 1, b.size))
    V[0] = b / beta
    H = np.zeros((limit + 1, limit))
    cs, sn = np.zeros(limit), np.zeros(limit)
    g = np.zeros(limit + 1)
    g[0] = beta
    k = 0
    for k in range(limit):
        w = apply(V[k])
        for i in range(k + 1):
            H[i, k] = float(V[i] @ w)
            w -= H[i, k] * V[i]
        h_next = float(np.linalg.norm(w))
        H[k + 1, k] = h_next
        if h_next > 1e-300:
            V[k + 1] = w / h_next
        for i in range(k):  # the earlier rotations on the new column
            H[i, k], H[i + 1, k] = cs[i] * H[i, k] + sn[i] * H[i + 1, k], -sn[i] * H[i, k] + cs[i] * H[i + 1, k]
        r = np.hypot(H[k, k], H[k + 1, k])
        cs[k], sn[k] = (H[k, k] / r, H[k + 1, k] / r) if r > 0 else (1.0, 0.0)
        H[k, k], H[k + 1, k] = r, 0.0
        g[k + 1], g[k] = -sn[k] * g[k], cs[k] * g[k]
        if abs(g[k + 1]) <= rtol * beta or h_next <= 1e-300:
            break
    k += 1
    diag = np.diag(H[:k, :k])
    y = np.linalg.solve(np.triu(H[:k, :k]) + np.diag(np.where(diag == 0.0, 1.0, 0.0)), g[:k])
    return V[:k].T @ y, abs(g[k]) / beta, k


def newton(residual, jacobian, x: np.ndarray, atol: float, limit: int | None = None):
    """Solve ``F(x) = 0`` from ``x`` until the out-of-balance force is at most ``atol``.

    ``residual(x, tangent)`` returns ``(F, force, state)``: the preconditioned residual, the
    out-of-balance force (N/m) the stop test measures and the state of ``x`` (with its tangent if
    asked); ``jacobian(state, F)`` the Jacobian's action ``v ↦ F′ v = v - M v`` at a state.

    Where the line search finds no decrease along Newton's step (the tangent's linearization
    holds only very near ``x``: points crossing the yield surface, a nearly singular tangent where
    flow far from associated localizes) the step is regularized towards the constant-stiffness
    one: ``(I - (1 - θ) M) δ = -F`` for θ in :data:`REGULARIZATION` (θ = 1 is the elastic
    stiffness' step ``δ = -F``), and relaxed again after a success. Returns ``x``, its state, the
    residual evaluations and the Krylov steps taken; raises :class:`Stalled` when no θ gives a
    decrease, the force is not finite or after ``limit`` steps."""
    limit = NEWTON_ITERATIONS if limit is None else limit
    F, force, state = residual(x, True)
    evaluations, krylov = 1, 0
    norm = float(np.linalg.norm(F))
    eta, last, level = ETA_FIRST, None, 0
    history, norms = [force], [norm]
    best = (force, x, state)

    def stalled(reason):
        return Stalled(best[0], atol, evaluations, reason, best[1:], krylov)

    for step in range(limit + 1):
        check_time("plastic iteration", evaluations)
        if force <= atol:
            return x, state, evaluations, krylov
        if not np.isfinite(force) or step == limit:
            break
        if len(history) > STALL_STEPS and force > 0.5 * history[-1 - STALL_STEPS]:
            raise stalled(f"the force did not halve in {STALL_STEPS} Newton steps")
        if last is not None:  # Eisenstat–Walker, choice 2, with its safeguard
            eta = min(ETA_MAX, max(0.9 * (norm / last) ** 2, 0.9 * eta**2, ETA_MIN, 0.5 * atol / force))
        J = jacobian(state, F)
        while True:
            theta = REGULARIZATION[level]
            apply = J if theta == 0.0 else (lambda v, th=theta: th * v + (1.0 - th) * J(v))
            dx, rel, its = gmres(apply, -F, eta) if theta < 1.0 else (-F, 0.0, 0)
            krylov += its
            found, alpha, trial, used = _line_search(residual, x, dx, norm, max(norms[-MEMORY:]), rel)
            evaluations += used
            if found or level == len(REGULARIZATION) - 1:
                break
            level += 1
        if not found:
            raise stalled("no step decreased the residual")
        F_new, force_new, state_new = trial
        log.debug("newton %d: force %.3g -> %.3g (atol %.3g), step %.3g, θ %g, gmres %d steps to %.2g", step,
                  force, force_new, atol, alpha, theta, its, rel)
        level = max(level - 1, 0)
        x, F, force, state = x + alpha * dx, F_new, force_new, state_new
        history.append(force)
        if force < best[0]:
            best = (force, x, state)
        last, norm = norm, float(np.linalg.norm(F_new))
        norms.append(norm)
    raise stalled(f"{limit} Newton steps")


def _line_search(residual, x, dx, norm: float, ref: float, rel: float):
    """Backtracking along ``dx`` from ``x`` (``‖F(x)‖ = norm``, the linear solve's relative
    residual ``rel``) until Armijo's decrease of ``‖F‖`` from ``ref`` (the largest of the last
    :data:`MEMORY` norms: non-monotone, Grippo, Lampariello & Lucidi 1986, so that a step past
    points crossing the yield surface is not refused for a passing rise): whether found, the
    step, the residual at it and the evaluations used."""
    alpha, used = 1.0, 0
    slope = -2.0 * (1.0 - min(rel, 1.0)) * norm**2  # of ‖F‖² along dx at α = 0
    while alpha >= LEAST_STEP:
        trial = residual(x + alpha * dx, True)
        used += 1
        norm_new = float(np.linalg.norm(trial[0]))
        if np.isfinite(norm_new) and norm_new <= ref - ARMIJO * alpha * (1.0 - min(rel, 1.0)) * norm:
            return True, alpha, trial, used
        # the least of the quadratic model along the step, kept within [α/10, α/2]
        q = -slope * alpha**2 / (2.0 * (norm_new**2 - norm**2 - slope * alpha)) if np.isfinite(norm_new) else 0.0
        alpha = min(max(q, 0.1 * alpha), 0.5 * alpha)
    return False, 0.0, None, used


def solve_increment(residual, jacobian, flowing, x: np.ndarray, atol: float, endgame: float):
    """:func:`newton` on ``residual(x, tangent, frozen=None)``, finished, where it stalls with a
    force below ``endgame``, by active-set steps: the points that flow at the best iterate
    (``flowing(state)``, (P,) bool) are frozen, so the return is smooth and Newton converges on
    it; then the true state is checked and the set updated (the primal–dual active-set method of
    contact problems, Hintermüller, Ito & Kunisch 2002). Where points cross the yield surface from
    one iterate to the next (flow far from associated, the tangent nearly singular), the
    semismooth iteration cycles among them; with the set frozen it cannot. Returns as
    :func:`newton`."""
    try:
        return newton(residual, jacobian, x, atol)
    except Stalled as stall:
        if stall.force > endgame:
            raise
        evaluations, krylov = stall.iterations, stall.krylov
        x, state = stall.best
        force, seen = stall.force, []  # the sets tried, and whether solved to the tolerance
        for _ in range(ACTIVE_SET_STEPS):
            frozen = flowing(state)
            again = [tight for s, tight in seen if np.array_equal(frozen, s)]
            if any(again):
                break  # a cycle of sets
            # each new set only as far as it is right (a tenth of the true force), then checked; a
            # set met again to the tolerance
            target = 0.5 * atol if again else max(0.5 * atol, 0.1 * force)
            seen.append((frozen, target == 0.5 * atol))
            try:
                x, _, its, kry = newton(lambda y, tangent: residual(y, tangent, frozen), jacobian, x, target)
            except Stalled as inner:
                evaluations += inner.iterations
                break
            evaluations, krylov = evaluations + its + 1, krylov + kry
            F, force, state = residual(x, True)
            log.debug("active set %d: %d points flow, force %.3g (atol %.3g)", len(seen), int(frozen.sum()), force,
                      atol)
            if force <= atol:
                return x, state, evaluations, krylov
        raise Stalled(stall.force, atol, evaluations, stall.reason + ", nor active-set steps", stall.best, krylov)
