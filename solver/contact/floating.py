"""Contact of a lining whose segments float (SPEC §1.6): the bolt-point method over every rigid mode.

Notation (:mod:`solver.fe.flexibility`, :mod:`solver.contact.friction`): R contact rows (the interface's,
then the joints' of :mod:`solver.lining.joints`), tractions ``t`` (Pa), weights ``W = diag(w)`` (m),
the jumps ``J = d - S W t - G a`` with ``a`` (k,) the amplitudes of the lining's rigid modes
and ``G`` (R, k) their jumps, and the balance of every mode ``F + Gᵀ W t = 0`` (``F`` the
loads on the modes, N/m). A row is

- *unilateral* (a normal row of a frictionless or Coulomb interface, every joint's normal row):
  t ≥ 0, gap = g0 - J ≥ 0, t·gap = 0;
- *equality* (bonded: the interface's rows, a bonded joint's tangential rows): J = 0, t free;
- *friction* (the tangential row of a Coulomb interface or joint, paired with its normal row
  p): |t| ≤ μ t_p, J = 0 where |t| < μ t_p, J along t where |t| = μ t_p.

The monolithic lining has one mode (its vertical translation) and the paper's bolt: one node
held closed, its pressure free, the trial accepted when that pressure is not negative
(Theorem 3.3; :mod:`solver.contact.bolt`). Here every segment brings its modes (the vertical
translation of one cut by the symmetry line, two translations and a rotation otherwise), so a
trial holds a *bolt set*: unilateral rows kept closed with free tractions, chosen so that they
and the always-held equality rows fix every mode (the rows' ``G`` span Rᵏ). With the bolt set
the problem has a unique solution, computed exactly by the primal-dual active-set method of
:mod:`solver.contact.friction` (each step one dense solve of the sets' rows and the k balances); the
trial is accepted when every bolt's traction is non-negative, which makes the bolted solution
the contact solution (each bolt then satisfies t ≥ 0, gap = 0). Otherwise, as in the paper,
the rejected bolts are dropped and the set is completed from the rows pressed hardest in the
rejected solution. The first bolt set is read from the all-closed solution, where the lining
presses where it rests.

A segment that no set of compressive rows can hold (a mode that every row leaves free, or whose
every holding row would pull) is not pinned: the solve fails, naming the segment and its mode.
On a cycle of the sets (Coulomb friction is not monotone) the friction bound is frozen (Tresca)
and the bolted problem, the bolts eliminated by the balances, is a box-constrained QP solved
exactly (:func:`solver.contact.friction._box_qp`), then the set iteration resumes from its answer.
"""
from __future__ import annotations

import functools
import logging
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as la

from .bolt import BoltedSolution, NoAdmissibleBoltError, NotConvergedError
from ..errors import SolverError
from .friction import _box_qp
from ..limits import check_time

log = logging.getLogger(__name__)

UNILATERAL, EQUALITY, FRICTION = 0, 1, 2


class DriftError(SolverError):
    """A rigid mode of a segment that no contact row can hold."""


@dataclass(frozen=True)
class FloatingProblem:
    """See the module docstring. ``kind`` (R,) of :data:`UNILATERAL`, :data:`EQUALITY`,
    :data:`FRICTION`; ``partner`` (R,) a friction row's normal row (-1 otherwise); ``mu`` (R,);
    ``labels`` (k,) what each mode is (for errors); ``p_scale`` (Pa) the pressure scale of the
    KKT measure; ``where`` (R,) a description of each row (bolt records)."""

    S: np.ndarray
    d: np.ndarray
    g0: np.ndarray
    w: np.ndarray
    G: np.ndarray
    F: np.ndarray
    kind: np.ndarray
    partner: np.ndarray
    mu: np.ndarray
    labels: tuple[str, ...]
    p_scale: float
    where: tuple[str, ...] = ()
    #: (R,) rows of one group (a joint's strip) are bolts together only if no other row will do:
    #: an open joint presses on its strip's edge alone, so its second row would pull
    group: np.ndarray | None = None

    @property
    def k(self) -> int:
        return self.G.shape[1]

    @functools.cached_property
    def WSW(self) -> np.ndarray:
        return (self.w[:, None] * self.S) * self.w[None, :]

    def jumps(self, t: np.ndarray, a: np.ndarray) -> np.ndarray:
        return self.d - self.S @ (self.w * t) - self.G @ a

    def target(self) -> np.ndarray:
        """What J is held at on a held row: g0 on unilateral rows (closed), 0 elsewhere."""
        return np.where(self.kind == UNILATERAL, self.g0, 0.0)


@dataclass
class BoltSetTrial:
    rows: list[int]
    where: list[str]
    tractions: list[float]
    iterations: int
    accepted: bool


@dataclass(kw_only=True)
class FloatingSolution(BoltedSolution):
    """Tractions ``t`` (R,) and the modes' amplitudes ``a`` (k,); ``bolts`` the accepted bolt set."""

    t: np.ndarray
    bolts: list[int] = field(default_factory=list)


@dataclass
class _Sets:
    held: np.ndarray    # unilateral rows in contact
    stick: np.ndarray   # friction rows stuck
    slip: np.ndarray    # friction rows slipping
    sign: np.ndarray    # slip direction

    def key(self) -> bytes:
        return np.packbits(np.r_[self.held, self.stick, self.slip, self.sign > 0]).tobytes()


def _closed(fp: FloatingProblem) -> _Sets:
    R = fp.d.size
    return _Sets(fp.kind == UNILATERAL, fp.kind == FRICTION, np.zeros(R, bool), np.zeros(R))


def _solve_sets(fp: FloatingProblem, SW: np.ndarray, sets: _Sets, bolts) -> tuple[np.ndarray, np.ndarray]:
    """t (R,) and a (k,) of the sets: J = target on held rows (contact, bolts, equality, stick),
    t = μσ t_p on slipping rows, t = 0 elsewhere, every mode balanced."""
    held = sets.held | sets.stick | (fp.kind == EQUALITY)
    held[list(bolts)] = True
    H = np.flatnonzero(held)
    slip = np.flatnonzero(sets.slip)
    n, k = H.size, fp.k
    rhs = np.r_[fp.d[H] - fp.target()[H], -fp.F]
    y = None if slip.size else _symmetric(fp, H, rhs)
    if y is None:  # slipping rows make the system unsymmetric: LU of the whole
        col = np.full(fp.d.size, -1)
        col[H] = np.arange(n)
        wG = fp.w[:, None] * fp.G
        A = np.zeros((n + k, n + k))
        A[:n, :n] = SW[np.ix_(H, H)]
        A[:n, n:] = fp.G[H]
        A[n:, :n] = wG[H].T
        if slip.size:
            f = fp.mu[slip] * sets.sign[slip]
            pc = col[fp.partner[slip]]
            np.add.at(A[:n].T, pc, (SW[np.ix_(H, slip)] * f).T)
            np.add.at(A[n:].T, pc, (wG[slip] * f[:, None]))
        y = np.linalg.solve(A, rhs)
    t = np.zeros(fp.d.size)
    t[H] = y[:n]
    if slip.size:
        t[slip] = fp.mu[slip] * sets.sign[slip] * t[fp.partner[slip]]
    return t, y[n:]


def _symmetric(fp: FloatingProblem, H: np.ndarray, rhs: np.ndarray) -> np.ndarray | None:
    """The sets' system without slipping rows, by the Cholesky factor of the flexibility block:
    with its rows scaled by w it is ``[[W S W, W G], [(W G)ᵀ, 0]]`` (as
    :func:`solver.contact.bolt.solve_on_set`); None if the block is not positive definite."""
    w = fp.w[H]
    A = fp.WSW[np.ix_(H, H)]
    C = w[:, None] * fp.G[H]
    try:
        factor = la.cho_factor(A, check_finite=False)
    except la.LinAlgError:
        return None
    n = H.size
    X = la.cho_solve(factor, np.column_stack([w * rhs[:n], C]), check_finite=False)
    # [A C; Cᵀ 0][t; a] = [w r; -F]: a from the k×k Schur complement Cᵀ A⁻¹ C
    a = la.solve(C.T @ X[:, 1:], C.T @ X[:, 0] - rhs[n:], check_finite=False)
    return np.r_[X[:, 0] - X[:, 1:] @ a, a]


def _update(fp: FloatingProblem, t: np.ndarray, J: np.ndarray, c: float, bolts) -> _Sets:
    """Sets from the natural maps (as :func:`solver.contact.friction._update`), bolts held."""
    uni, fri = fp.kind == UNILATERAL, fp.kind == FRICTION
    z = t - c * (fp.g0 - J)
    held = uni & (z > 0)
    held[list(bolts)] = True
    p = np.where(fri, fp.partner, 0)
    bound = np.where(fri, fp.mu * np.maximum(z[p], 0.0), 0.0)
    zt = t + c * J
    on = fri & held[p] & (bound > 0)
    stick = on & (np.abs(zt) <= bound)
    slip = on & ~stick
    return _Sets(held, stick, slip, np.where(slip, np.sign(zt), 0.0))


def kkt(fp: FloatingProblem, t: np.ndarray, a: np.ndarray, bolts=()) -> float:
    """Largest relative violation of the conditions of every row and of the balances (the
    bolts' sign excepted: that is the trial's test)."""
    J = fp.jumps(t, a)
    p_ref = max(fp.p_scale, float(np.max(np.abs(t), initial=0.0)))
    u_ref = max(float(np.max(np.abs(fp.d))), float(np.max(np.abs(fp.S @ (fp.w * t)))),
                float(np.max(np.abs(fp.G @ a))), float(np.max(fp.g0)), 1e-300)
    uni, eq, fri = fp.kind == UNILATERAL, fp.kind == EQUALITY, fp.kind == FRICTION
    signed = uni.copy()
    signed[list(bolts)] = False
    gap = fp.g0 - J
    parts = [max(0.0, -float(gap[uni].min(initial=0.0))) / u_ref,
             float(np.max(np.abs(t[uni] * gap[uni]), initial=0.0)) / (p_ref * u_ref),
             max(0.0, -float(t[signed].min(initial=0.0))) / p_ref,
             float(np.max(np.abs(J[eq]), initial=0.0)) / u_ref]
    if fri.any():
        bound = fp.mu[fri] * np.maximum(t[fp.partner[fri]], 0.0)
        nat = t[fri] - np.clip(t[fri] + (p_ref / u_ref) * J[fri], -bound, bound)
        parts.append(float(np.max(np.abs(nat))) / p_ref)
    wG = fp.w[:, None] * fp.G
    balance = fp.F + wG.T @ t
    scale = np.abs(fp.F) + np.abs(wG).T @ np.abs(t)
    parts.append(float(np.max(np.abs(balance) / np.maximum(scale, 1e-300))))
    return max(parts)


def _span(G: np.ndarray, rows) -> tuple[np.ndarray, int]:
    """An orthonormal basis (k, r) of the span of ``G[rows]`` (columns scaled to unit size)."""
    if len(rows) == 0:
        return np.zeros((G.shape[1], 0)), 0
    Q, Rr, _ = la.qr(G[list(rows)].T, mode="economic", pivoting=True)
    d = np.abs(np.diag(Rr))
    r = int(np.sum(d > 1e-9 * max(d.max(initial=0.0), 1e-300)))
    return Q[:, :r], r


def choose_bolts(fp: FloatingProblem, score: np.ndarray, *, keep=(), exclude=()) -> list[int]:
    """Unilateral rows that, with ``keep`` and the equality rows, fix every mode: the rows with
    the largest ``score`` first (a row joins when it adds a direction). Raises
    :class:`DriftError` naming the modes no admissible row can hold."""
    G = fp.G / np.maximum(np.max(np.abs(fp.G), axis=0), 1e-300)
    base = list(np.flatnonzero(fp.kind == EQUALITY)) + list(keep)
    Q, r = _span(G, base)
    bolts = list(keep)
    excluded = set(exclude) | set(keep)
    usable = (fp.kind == UNILATERAL) & np.any(G != 0, axis=1)
    usable[list(excluded)] = False
    order = np.argsort(-score, kind="stable")
    order = order[usable[order]]
    group = fp.group if fp.group is not None else -1 - np.arange(fp.d.size)
    for first_of_group in (True, False):
        for i in order:
            if r == fp.k:
                break
            if i in bolts or (first_of_group and np.any(group[bolts] == group[i])):
                continue
            g = G[i] - Q @ (Q.T @ G[i])
            if np.linalg.norm(g) > 1e-6 * np.linalg.norm(G[i]):
                bolts.append(int(i))
                Q, r = _span(G, base + bolts[len(keep):])
    if r < fp.k:
        free = la.null_space(Q.T) if r else np.eye(fp.k)
        named = sorted({fp.labels[int(np.argmax(np.abs(free[:, j])))] for j in range(free.shape[1])})
        reason = ("no contact row can hold it" if not exclude else
                  "every way of holding it by contact would pull (negative contact tractions)")
        raise DriftError("lining.joints: a segment would drift: " + "; ".join(named) + f" ({reason}); the "
                         "segment is not pinned to give an answer. Check the loads, the joints' strip and shear, "
                         "and the interface model")
    return bolts


def _active_set(fp, SW, c, bolts, sets, *, tol, max_iter):
    """Set iteration: (t, a, sets, steps, status) with status 'done', 'cycle' or 'limit'."""
    seen: set[bytes] = set()
    t, a = np.zeros(fp.d.size), np.zeros(fp.k)
    for step in range(1, max_iter + 1):
        check_time("segmental contact active-set iteration", step)
        seen.add(sets.key())
        try:
            t, a = _solve_sets(fp, SW, sets, bolts)
        except np.linalg.LinAlgError:
            return t, a, sets, step, "cycle"
        new = _update(fp, t, fp.jumps(t, a), c, bolts)
        if new.key() == sets.key():
            return t, a, sets, step, ("done" if kkt(fp, t, a, bolts) <= 0.5 * tol else "cycle")
        if new.key() in seen:
            return t, a, new, step, "cycle"
        sets = new
    return t, a, sets, max_iter, "limit"


def _tresca(fp: FloatingProblem, WSW: np.ndarray, bolts, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The bolted problem with the friction bound frozen at μ max(t_p, 0) of ``t``, exactly: k rows
    of the free ones (bolts, equality rows) are eliminated by the balances, the rest is a
    box-constrained QP in the other tractions."""
    R, k = fp.d.size, fp.k
    uni, eq, fri = fp.kind == UNILATERAL, fp.kind == EQUALITY, fp.kind == FRICTION
    bound = np.where(fri, fp.mu * np.maximum(t[np.where(fri, fp.partner, 0)], 0.0), 0.0)
    free_rows = sorted(set(np.flatnonzero(eq)) | set(bolts))
    C = fp.w[:, None] * fp.G
    _, _, piv = la.qr(C[free_rows].T, mode="economic", pivoting=True)
    basis = np.array(free_rows)[piv[:k]]
    variable = np.ones(R, bool)
    variable[basis] = False
    variable &= ~(fri & (bound <= 0))
    x_rows = np.flatnonzero(variable)
    CB = C[basis]  # (k, k)
    E = np.zeros((R, x_rows.size))
    E[x_rows, np.arange(x_rows.size)] = 1.0
    E[basis] = -la.solve(CB.T, C[x_rows].T)
    t0 = np.zeros(R)
    t0[basis] = -la.solve(CB.T, fp.F)
    v = fp.w * (fp.d - fp.target()) - WSW @ t0
    H = E.T @ WSW @ E
    b = E.T @ v
    lower = np.where(uni[x_rows], 0.0, np.where(fri[x_rows], -bound[x_rows], -np.inf))
    upper = np.where(fri[x_rows], bound[x_rows], np.inf)
    bolted = np.isin(x_rows, list(bolts)) | eq[x_rows]
    lower[bolted] = -np.inf
    x = _box_qp(0.5 * (H + H.T), b, lower, upper, np.clip(t[x_rows], lower, upper))
    out = t0 + E @ x
    a = la.solve(fp.G[basis], fp.d[basis] - (fp.S @ (fp.w * out))[basis] - fp.target()[basis])
    return out, a


def solve_bolted(fp: FloatingProblem, bolts, sets: _Sets, *, tol: float, max_iter: int):
    """The problem with the bolt set held: (t, a, sets, iterations); the set iteration, and on a
    cycle Tresca steps each followed by the set iteration (:func:`solver.contact.friction.solve_bolted`)."""
    SW = fp.S * fp.w[None, :]
    c = 1.0 / float(np.max(np.diag(fp.S) * fp.w))
    t, a, sets, steps, status = _active_set(fp, SW, c, bolts, sets, tol=tol, max_iter=max_iter)
    if status == "done":
        return t, a, sets, steps
    log.info("segmental contact: active sets %s after %d steps; Tresca fixed point", status, steps)
    WSW = fp.WSW
    while steps < max_iter:
        if steps % 64 == 0:
            check_time("segmental contact fixed-point iteration", steps)
        t, a = _tresca(fp, WSW, bolts, t)
        steps += 1
        if kkt(fp, t, a, bolts) <= 0.5 * tol:
            return t, a, _update(fp, t, fp.jumps(t, a), c, bolts), steps
        t2, a2, s2, n, status = _active_set(fp, SW, c, bolts, _update(fp, t, fp.jumps(t, a), c, bolts), tol=tol,
                                            max_iter=min(10, max_iter - steps))
        steps += n
        if status == "done":
            return t2, a2, s2, steps
    raise NotConvergedError(
        f"lining.joints: the segmental contact problem did not reach solver.tolerance={tol:g} in "
        f"solver.max_iterations={max_iter} steps; raise solver.max_iterations or lower the friction")


def solve_floating(fp: FloatingProblem, *, tol: float, max_iterations: int) -> FloatingSolution:
    """The contact problem of a lining with several floating parts (see the module docstring)."""
    SW = fp.S * fp.w[None, :]
    # where the lining presses when every row is closed: the first bolt set's guide
    free_all = _span(fp.G / np.maximum(np.max(np.abs(fp.G), axis=0), 1e-300),
                     [i for i in range(fp.d.size) if np.any(fp.G[i] != 0)])[1]
    if free_all < fp.k:
        choose_bolts(fp, np.zeros(fp.d.size))  # raises, naming the modes no row touches
    closed = _closed(fp)
    t, _ = _solve_sets(fp, SW, closed, [])
    bolts = choose_bolts(fp, t)
    sets = closed
    rejected: set[int] = set()
    trials: list[BoltSetTrial] = []
    total = 0
    p_ref = fp.p_scale
    while True:
        t, a, sets, its = solve_bolted(fp, bolts, sets, tol=tol, max_iter=max_iterations)
        total += its
        bad = [b for b in bolts if t[b] < -tol * max(p_ref, float(np.max(np.abs(t))))]
        where = [fp.where[b] if fp.where else str(b) for b in bolts]
        trials.append(BoltSetTrial(rows=[int(b) for b in bolts], where=where,
                                   tractions=[float(t[b]) for b in bolts], iterations=its, accepted=not bad))
        log.debug("bolt set %s: tractions %s", where, [t[b] for b in bolts])
        if not bad:
            return FloatingSolution(t=t, a=a, bolt=None, bolts=list(bolts), trials=trials, iterations=total,
                                    admissible=True)
        rejected |= set(bad)
        if len(trials) > 4 * fp.k + 20:
            raise NoAdmissibleBoltError(
                f"lining.joints: no admissible bolt set after {len(trials)} trials (a segment is held only by "
                "pulling contact rows); check the loads and solver.tolerance")
        bolts = choose_bolts(fp, t, keep=[b for b in bolts if b not in bad], exclude=rejected)
